#pragma once
// Errors in user-supplied input (files, options). Callers print what() on one line and
// exit with code 2; the message names the file and the field or line so the user can fix it.
#include <stdexcept>
#include <string>

namespace bms {

class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

// A numerical or solver failure on valid input (exit code 1).
class RuntimeFailure : public std::runtime_error {
 public:
  explicit RuntimeFailure(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace bms
