#pragma once
/// @file huge_pages.hpp
/// Large per-step arrays (gradient stencils, point state, element forces) on transparent huge
/// pages. A 4 KiB page holds the stencils of only about six particles, so a force pass over a
/// few hundred thousand particles misses the TLB every few points; with 2 MiB pages the same
/// pass is faster (measurements: docs/performance.md).
/// Debian's kernel runs THP in "madvise" mode, so memory gets huge pages only where asked for.
#include <cstddef>
#include <cstdlib>
#include <new>
#include <vector>

namespace rkfem
{
/// Advises the kernel to back [p, p + bytes) with huge pages (no-op off Linux, and for the
/// partial pages at either end). Effective for memory that has not been touched yet.
void advise_huge_pages(void* p, std::size_t bytes);

/// Storage aligned to a 64-byte cache line: what whole-line streaming stores of structure-of-
/// arrays fields need (core/stream_stores.hpp, store_batch8). glibc's own allocations of large
/// arrays start 16 bytes into a page.
template <class T> struct LineAllocator
{
    using value_type = T;
    LineAllocator() = default;
    template <class U> LineAllocator(const LineAllocator<U>&) noexcept {}
    T* allocate(std::size_t n)
    {
        const std::size_t bytes = (n * sizeof(T) + 63) / 64 * 64;
        void* p = std::aligned_alloc(64, bytes == 0 ? 64 : bytes);
        if (p == nullptr)
            throw std::bad_alloc();
        return static_cast<T*>(p);
    }
    void deallocate(T* p, std::size_t) noexcept { std::free(p); }
    template <class U> bool operator==(const LineAllocator<U>&) const noexcept { return true; }
};
/// A field whose storage starts on a cache line.
template <class T> using LineVector = std::vector<T, LineAllocator<T>>;

/// Moves v's contents into fresh storage advised for huge pages before it is touched (vectors
/// of 4 MiB and more; smaller ones are left alone). Later copy-assignments and swaps keep it.
template <class T, class A> void use_huge_pages(std::vector<T, A>& v)
{
    constexpr std::size_t threshold = std::size_t{4} << 20;
    if (v.size() * sizeof(T) < threshold)
        return;
    std::vector<T, A> w;
    w.reserve(v.size()); // a fresh mapping (glibc maps allocations this large on their own)
    advise_huge_pages(w.data(), w.capacity() * sizeof(T));
    w.insert(w.end(), v.begin(), v.end());
    v.swap(w);
}
} // namespace rkfem
