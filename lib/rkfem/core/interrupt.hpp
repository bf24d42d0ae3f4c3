#pragma once
/// @file interrupt.hpp
/// SIGINT and SIGTERM as a request to stop: the first one sets a flag that the run loop reads at
/// each step's end (it then writes the last state: a frame, the history row, summary.json marked
/// interrupted, a checkpoint when checkpoints are on) and restores the signal's default action,
/// so that a second one ends the process at once. The handler only stores to a lock-free atomic
/// (async-signal-safe).
namespace rkfem
{
/// Installs the handlers for SIGINT and SIGTERM (the driver's run, restart and study).
void install_interrupt_handlers();
/// The signal that asked to stop (SIGINT or SIGTERM), or 0.
int interrupt_signal();
/// "SIGINT", "SIGTERM" (or "signal N").
const char* interrupt_signal_name(int sig);
} // namespace rkfem
