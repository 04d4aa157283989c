#pragma once
/// @file stop_signal.hpp
/// SIGINT and SIGTERM during a long command (simulate, optimize): the first asks the run to
/// stop at its next safe point (after the current step or iteration) and restores the previous
/// action, so a second one ends the process at once.
///
/// Under mpirun, while rank 0 waits for the other ranks' load cases (a waiting message is set),
/// either signal ends rank 0 at once after writing that message: a rank that died cannot answer,
/// and the launcher signals the others when one dies. The iterations written so far stay.

#include <string>

namespace diffipc {

/// Installs the handlers and clears a previous stop request.
void catch_stop_signals();
/// The signal that asked to stop, 0 if none.
int stop_signal();
/// Restores the actions from before catch_stop_signals(); returns stop_signal().
int release_stop_signals();
/// Exit code of a run stopped by `signal`: 128 + the signal number, as shells report it.
inline int interrupted_exit_code(int signal) { return 128 + signal; }

/// Installs, outside catch_stop_signals(), handlers that write the waiting message (if one is set)
/// and end the process with interrupted_exit_code(); without one, the default action.
void end_on_signals_while_waiting();
/// The message to write if a signal comes now ("" : none; then a signal acts as before). At most
/// 4,000 bytes are kept.
void set_waiting_message(const std::string& message);

} // namespace diffipc
