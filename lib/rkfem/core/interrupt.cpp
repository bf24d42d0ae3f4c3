#include "rkfem/core/interrupt.hpp"

#include <atomic>
#include <csignal>

namespace rkfem
{
namespace
{
std::atomic<int> requested{0};
static_assert(std::atomic<int>::is_always_lock_free);

extern "C" void on_signal(int sig)
{
    requested.store(sig, std::memory_order_relaxed);
    std::signal(sig, SIG_DFL); // a second one ends the process
}
} // namespace

void install_interrupt_handlers()
{
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
}

int interrupt_signal()
{
    return requested.load(std::memory_order_relaxed);
}

const char* interrupt_signal_name(int sig)
{
    switch (sig)
    {
    case SIGINT:
        return "SIGINT";
    case SIGTERM:
        return "SIGTERM";
    default:
        return "a signal";
    }
}
} // namespace rkfem
