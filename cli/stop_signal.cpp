#include "cli/stop_signal.hpp"

#include <csignal>

namespace diffipc {

namespace {
    volatile std::sig_atomic_t g_stop_signal = 0;

    extern "C" void on_stop_signal(int signal)
    {
        g_stop_signal = signal;
        std::signal(signal, SIG_DFL);
    }
} // namespace

void catch_stop_signals()
{
    g_stop_signal = 0;
    std::signal(SIGINT, on_stop_signal);
    std::signal(SIGTERM, on_stop_signal);
}

int stop_signal() { return g_stop_signal; }

int release_stop_signals()
{
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
    return g_stop_signal;
}

} // namespace diffipc
