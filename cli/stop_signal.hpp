#pragma once
/// @file stop_signal.hpp
/// SIGINT and SIGTERM during a long command (simulate, optimize): the first asks the run to
/// stop at its next safe point (after the current step or iteration) and restores the default
/// action, so a second one ends the process at once.

namespace diffipc {

/// Installs the handlers and clears a previous stop request.
void catch_stop_signals();
/// The signal that asked to stop, 0 if none.
int stop_signal();
/// Restores the default actions; returns stop_signal().
int release_stop_signals();
/// Exit code of a run stopped by `signal`: 128 + the signal number, as shells report it.
inline int interrupted_exit_code(int signal) { return 128 + signal; }

} // namespace diffipc
