// Errors. Expected failures of a stage (no match, too few stars) are data in its result;
// exceptions are for bad input (InputError, exit status 1) and for bugs (anything else, exit 2).
#pragma once

#include <stdexcept>
#include <string>

namespace ssiu {

// Bad input: a one-line message that names the file and the field or problem.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
  // "FILE: WHAT", the form every input error takes.
  InputError(const std::string& file, const std::string& what)
      : std::runtime_error(file.empty() ? what : file + ": " + what) {}
};

}  // namespace ssiu
