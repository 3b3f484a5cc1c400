#pragma once
// Error types. Libraries throw; only apps/ turns them into exit codes and messages.
// Every what() is one line a user can act on: the file, the offending value, the fix.
#include <stdexcept>
#include <string>

namespace specula {

/// Base of every exception specula throws on purpose.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A file or value given to specula is malformed, inconsistent or unsupported.
class InputError : public Error {
 public:
  using Error::Error;
};

/// An API or command-line rule was broken by the caller; the message states the rule.
class UsageError : public Error {
 public:
  using Error::Error;
};

/// A third-party library (HDF5, OpenEXR, libpng, matio) or the OS reported failure; carries its message.
class LibraryError : public Error {
 public:
  using Error::Error;
};

/// The user asked the work to stop (Ctrl-C, SIGTERM); finished results were kept.
class Interrupted : public Error {
 public:
  Interrupted() : Error("interrupted") {}
  /// An interruption with a message saying what was kept and how to continue.
  explicit Interrupted(const std::string& what) : Error(what) {}
};

}  // namespace specula
