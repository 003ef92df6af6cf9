#include "tools/common/interrupt.hpp"

#include <csignal>

namespace epitrack::tools {

namespace {

// sig_atomic_t is the one type the C and C++ standards let a handler write; volatile keeps the
// polling loop from caching it.
volatile std::sig_atomic_t g_interrupt_signal = 0;

extern "C" void onInterruptSignal(int signal_number) { g_interrupt_signal = signal_number; }

}  // namespace

void installInterruptHandlers() {
  struct sigaction action {};
  action.sa_handler = onInterruptSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART | SA_RESETHAND;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

bool interruptRequested() { return g_interrupt_signal != 0; }

int interruptSignal() { return static_cast<int>(g_interrupt_signal); }

const char* interruptSignalName() {
  switch (g_interrupt_signal) {
    case SIGINT:
      return "SIGINT";
    case SIGTERM:
      return "SIGTERM";
    default:
      return "none";
  }
}

int interruptExitCode() { return 128 + interruptSignal(); }

}  // namespace epitrack::tools
