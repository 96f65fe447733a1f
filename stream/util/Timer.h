#pragma once
/// @file Timer.h
/// @brief The one wall-clock timer: a stopwatch and a scope timer for per-phase stats.

#include <chrono>

namespace penumbra {

/// @brief Measures elapsed wall-clock (steady) time from construction or the last reset().
class Stopwatch {
public:
    Stopwatch() : start_(std::chrono::steady_clock::now()) {}
    /// Restarts the measurement.
    void reset() { start_ = std::chrono::steady_clock::now(); }
    /// Seconds since construction or the last reset().
    double seconds() const {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    }

private:
    std::chrono::steady_clock::time_point start_;
};

/// @brief Adds the time spent in a scope to a caller's accumulator (per-phase stats).
class ScopedTimer {
public:
    /// @param accumulator receives += elapsed seconds when the timer is destroyed.
    explicit ScopedTimer(double& accumulator) : accumulator_(accumulator) {}
    ~ScopedTimer() { accumulator_ += watch_.seconds(); }
    ScopedTimer(const ScopedTimer&) = delete;
    ScopedTimer& operator=(const ScopedTimer&) = delete;
    /// Seconds since construction.
    double seconds() const { return watch_.seconds(); }

private:
    double& accumulator_;
    Stopwatch watch_;
};

}  // namespace penumbra
