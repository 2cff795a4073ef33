// Errors that reach the operator. Every message says what went wrong, where, and what to do,
// on one line, so that sherdctl / sherdd can print it unchanged.
#pragma once

#include <stdexcept>
#include <string>

namespace sherd {

// Bad input the user can fix: a config error, an unreadable file, an unknown scan id.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A hardware (or simulated hardware) failure: timeout, stall, disconnect, device not found.
class DeviceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A processing stage could not produce a result from valid input (e.g. no overlap between views).
class ProcessingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace sherd
