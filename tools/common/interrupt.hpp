#pragma once

// SIGINT/SIGTERM as a request to stop at the next consistent point (issue 9 "No data lost").
// The handler only stores the signal number in a lock-free flag (async-signal-safe); the command
// polls `interruptRequested()` between frames and between stages and then writes what is
// consistent. The handler is installed with SA_RESETHAND: a second Ctrl-C kills the process at
// once (no cleanup), for a user who does not want to wait.

namespace epitrack::tools {

/// Installs the handler for SIGINT and SIGTERM (SA_RESTART, so blocking reads continue and
/// end on their own: a pipe closes, a camera delivers its next frame).
void installInterruptHandlers();

/// True once SIGINT or SIGTERM arrived.
[[nodiscard]] bool interruptRequested();

/// The signal that asked to stop (SIGINT, SIGTERM), 0 when none.
[[nodiscard]] int interruptSignal();

/// "SIGINT", "SIGTERM" or "none".
[[nodiscard]] const char* interruptSignalName();

/// Exit code of an interrupted command: 128 + the signal number (130 for SIGINT, 143 for SIGTERM),
/// the shell's convention for a process ended by a signal.
[[nodiscard]] int interruptExitCode();

}  // namespace epitrack::tools
