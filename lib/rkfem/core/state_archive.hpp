#pragma once
/// @file state_archive.hpp
/// Named byte blobs of a run's state: what a checkpoint holds (io/checkpoint.hpp writes and reads
/// it as HDF5). Every value goes in and comes out bit for bit: arrays of trivially copyable
/// types (doubles, indices, material state structs) and single values. Reading an entry that is
/// missing, or whose size is not a whole number of the type asked for, throws Error naming it.
#include <cstddef>
#include <cstring>
#include <map>
#include <string>
#include <type_traits>
#include <vector>

#include "rkfem/core/error.hpp"

namespace rkfem
{
class StateArchive
{
  public:
    void put_bytes(const std::string& name, const void* data, std::size_t bytes)
    {
        std::vector<unsigned char>& b = entries_[name];
        b.resize(bytes);
        if (bytes > 0)
            std::memcpy(b.data(), data, bytes);
    }
    const std::vector<unsigned char>& bytes(const std::string& name) const
    {
        const auto it = entries_.find(name);
        if (it == entries_.end())
            throw Error("checkpoint has no entry '" + name +
                        "' (written by another version of rkfem, or for another deck)");
        return it->second;
    }
    bool has(const std::string& name) const { return entries_.count(name) != 0; }

    /// An array (std::vector or any container with data(), size(), resize()).
    template <class C> void put(const std::string& name, const C& c)
    {
        using T = std::remove_cv_t<std::remove_reference_t<decltype(*c.data())>>;
        static_assert(std::is_trivially_copyable_v<T>);
        put_bytes(name, c.data(), c.size() * sizeof(T));
    }
    template <class C> void get(const std::string& name, C& c) const
    {
        using T = std::remove_cv_t<std::remove_reference_t<decltype(*c.data())>>;
        static_assert(std::is_trivially_copyable_v<T>);
        copy_out(name, c);
    }
    /// An array of plain structs that hold fixed-size Eigen vectors (Eigen declares copy
    /// constructors, so they are not trivially copyable, but they are their bytes).
    template <class T> void put_raw(const std::string& name, const std::vector<T>& v)
    {
        static_assert(std::is_standard_layout_v<T> && std::is_trivially_destructible_v<T>);
        put_bytes(name, v.data(), v.size() * sizeof(T));
    }
    template <class T> void get_raw(const std::string& name, std::vector<T>& v) const
    {
        static_assert(std::is_standard_layout_v<T> && std::is_trivially_destructible_v<T>);
        copy_out(name, v);
    }
    /// An array that must keep its size (state sized by the model the deck builds).
    template <class C> void get_same_size(const std::string& name, C& c) const
    {
        const std::size_t n = c.size();
        get(name, c);
        if (c.size() != n)
            throw Error("checkpoint entry '" + name + "' holds " + std::to_string(c.size()) +
                        " values where the model has " + std::to_string(n) + " (a checkpoint of another deck)");
    }
    template <class T> void put_value(const std::string& name, const T& v)
    {
        static_assert(std::is_trivially_copyable_v<T>);
        put_bytes(name, &v, sizeof(T));
    }
    template <class T> T value(const std::string& name) const
    {
        static_assert(std::is_trivially_copyable_v<T>);
        const std::vector<unsigned char>& b = bytes(name);
        if (b.size() != sizeof(T))
            throw Error("checkpoint entry '" + name + "' has " + std::to_string(b.size()) + " bytes, expected " +
                        std::to_string(sizeof(T)));
        T v;
        std::memcpy(static_cast<void*>(&v), b.data(), sizeof(T));
        return v;
    }
    void put_text(const std::string& name, const std::string& s) { put_bytes(name, s.data(), s.size()); }
    std::string text(const std::string& name) const
    {
        const std::vector<unsigned char>& b = bytes(name);
        return std::string(b.begin(), b.end());
    }

    const std::map<std::string, std::vector<unsigned char>>& entries() const { return entries_; }

  private:
    /// The entry's bytes into c, resized to a whole number of its values.
    template <class C> void copy_out(const std::string& name, C& c) const
    {
        using T = std::remove_cv_t<std::remove_reference_t<decltype(*c.data())>>;
        const std::vector<unsigned char>& b = bytes(name);
        if (b.size() % sizeof(T) != 0)
            throw Error("checkpoint entry '" + name + "' has " + std::to_string(b.size()) +
                        " bytes, not a whole number of " + std::to_string(sizeof(T)) + "-byte values");
        c.resize(b.size() / sizeof(T));
        if (!b.empty())
            std::memcpy(static_cast<void*>(c.data()), b.data(), b.size());
    }
    std::map<std::string, std::vector<unsigned char>> entries_;
};
} // namespace rkfem
