#pragma once
/// @file error.hpp
/// Two tiers of checks: RKFEM_REQUIRE (always on; user-facing; throws rkfem::Error with the
/// message streamed from the offending values) and RKFEM_ASSERT (debug-only internal invariant).
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

namespace rkfem
{
/// Every error the library reports to a user. The message is complete and one line.
class Error : public std::runtime_error
{
  public:
    explicit Error(const std::string& what) : std::runtime_error(what) {}
};

/// A run that became unstable (NaN, inverted element, energy blow-up). Carries where and when.
class InstabilityError : public Error
{
  public:
    explicit InstabilityError(const std::string& what) : Error(what) {}
    /// `state_time`: the time of the state that failed (a step's end or a stage), when known
    InstabilityError(const std::string& what, double state_time) : Error(what), time(state_time) {}
    double time = std::numeric_limits<double>::quiet_NaN();
};
} // namespace rkfem

#define RKFEM_REQUIRE(cond, msg)                                                                                       \
    do                                                                                                                 \
    {                                                                                                                  \
        if (!(cond))                                                                                                   \
        {                                                                                                              \
            std::ostringstream rkfem_oss_;                                                                             \
            rkfem_oss_ << msg;                                                                                         \
            throw ::rkfem::Error(rkfem_oss_.str());                                                                    \
        }                                                                                                              \
    } while (false)

#ifndef NDEBUG
#define RKFEM_ASSERT(cond, msg)                                                                                        \
    do                                                                                                                 \
    {                                                                                                                  \
        if (!(cond))                                                                                                   \
        {                                                                                                              \
            std::ostringstream rkfem_oss_;                                                                             \
            rkfem_oss_ << __FILE__ << ":" << __LINE__ << ": assertion '" #cond "' failed: " << msg;                    \
            throw ::rkfem::Error(rkfem_oss_.str());                                                                    \
        }                                                                                                              \
    } while (false)
#else
#define RKFEM_ASSERT(cond, msg)                                                                                        \
    do                                                                                                                 \
    {                                                                                                                  \
    } while (false)
#endif
