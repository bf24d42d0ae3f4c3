#pragma once
/// @file time_function.hpp
/// Scalar functions of time used by boundary conditions and loads: a constant, a piecewise-linear
/// table (held constant past its ends), or a triangular pulse (peak at `start`, linear decay to
/// zero at `start + duration`, zero before `start`), each times `scale`.
#include <vector>

#include "rkfem/core/types.hpp"

namespace rkfem
{
struct TimeFunction
{
    enum class Kind
    {
        Constant,
        Table,
        Triangular
    };
    Kind kind = Kind::Constant;
    real_t value = 0.0;         ///< Constant: the value (SI)
    std::vector<real_t> times;  ///< Table: strictly increasing times [s]
    std::vector<real_t> values; ///< Table: values (SI) at `times`
    real_t peak = 0.0;          ///< Triangular: peak value (SI)
    real_t start = 0.0;         ///< Triangular: arrival time [s]
    real_t duration = 0.0;      ///< Triangular: decay time to zero [s]
    real_t scale = 1.0;

    static TimeFunction constant(real_t v)
    {
        TimeFunction f;
        f.value = v;
        return f;
    }

    real_t operator()(real_t t) const
    {
        switch (kind)
        {
        case Kind::Constant:
            return scale * value;
        case Kind::Triangular:
            if (t < start || t > start + duration)
                return 0.0;
            return scale * peak * (1.0 - (t - start) / duration);
        case Kind::Table:
        {
            if (t <= times.front())
                return scale * values.front();
            if (t >= times.back())
                return scale * values.back();
            std::size_t hi = 1;
            while (times[hi] < t)
                ++hi;
            const real_t s = (t - times[hi - 1]) / (times[hi] - times[hi - 1]);
            return scale * ((1.0 - s) * values[hi - 1] + s * values[hi]);
        }
        }
        return 0.0;
    }
};
} // namespace rkfem
