#include "cli/stop_signal.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstring>

namespace diffipc {

namespace {
    volatile std::sig_atomic_t g_stop_signal = 0;
    using Handler = void (*)(int);
    Handler g_previous_int = SIG_DFL, g_previous_term = SIG_DFL;

    // The waiting message: written whole before its length is published.
    char g_waiting[4096];
    volatile std::sig_atomic_t g_waiting_length = 0;

    // Async-signal-safe: write(2) and _exit only.
    void end_if_waiting(int signal)
    {
        const std::sig_atomic_t length = g_waiting_length;
        if (length <= 0)
            return;
        std::atomic_signal_fence(std::memory_order_acquire); // the bytes written before the length was
        ssize_t written = 0;
        while (written < length) {
            const ssize_t n = ::write(STDERR_FILENO, g_waiting + written, size_t(length - written));
            if (n <= 0)
                break;
            written += n;
        }
        ::_exit(interrupted_exit_code(signal));
    }

    extern "C" void on_stop_signal(int signal)
    {
        end_if_waiting(signal);
        g_stop_signal = signal;
        std::signal(signal, signal == SIGINT ? g_previous_int : g_previous_term);
    }

    extern "C" void on_signal_while_waiting(int signal)
    {
        end_if_waiting(signal);
        std::signal(signal, SIG_DFL);
        std::raise(signal);
    }
} // namespace

void catch_stop_signals()
{
    g_stop_signal = 0;
    g_previous_int = std::signal(SIGINT, on_stop_signal);
    g_previous_term = std::signal(SIGTERM, on_stop_signal);
    if (g_previous_int == SIG_ERR || g_previous_int == on_stop_signal)
        g_previous_int = SIG_DFL;
    if (g_previous_term == SIG_ERR || g_previous_term == on_stop_signal)
        g_previous_term = SIG_DFL;
}

int stop_signal() { return g_stop_signal; }

int release_stop_signals()
{
    std::signal(SIGINT, g_previous_int);
    std::signal(SIGTERM, g_previous_term);
    return g_stop_signal;
}

void end_on_signals_while_waiting()
{
    std::signal(SIGINT, on_signal_while_waiting);
    std::signal(SIGTERM, on_signal_while_waiting);
}

void set_waiting_message(const std::string& message)
{
    g_waiting_length = 0;
    std::atomic_signal_fence(std::memory_order_seq_cst); // no handler reads the bytes while they change
    const size_t length = std::min(message.size(), sizeof g_waiting - 1);
    std::memcpy(g_waiting, message.data(), length);
    std::atomic_signal_fence(std::memory_order_release); // the bytes before the length that publishes them
    g_waiting_length = std::sig_atomic_t(length);
}

} // namespace diffipc
