#pragma once
// A run's saved state (an NMF checkpoint, say): one small HDF5 file of named scalar attributes and float64 vectors
// and matrices, identified by attributes specula_format and format_version, written to a temporary sibling and
// renamed so a file on disk is always complete. HDF5 stays inside store/.
#include <Eigen/Core>

#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace specula::store {

/// Writes a state file: fields in call order, then commit() renames it into place (nothing appears without it).
class StateFileWriter {
 public:
  /// Creates the temporary file of `path` and records `format` and `version`.
  StateFileWriter(const std::filesystem::path& path, std::string_view format, long long version);
  ~StateFileWriter();
  StateFileWriter(const StateFileWriter&) = delete;
  StateFileWriter& operator=(const StateFileWriter&) = delete;

  /// Writes the string attribute `name`.
  void attr(const std::string& name, std::string_view value);
  /// Writes the int64 attribute `name`.
  void attr(const std::string& name, long long value);
  /// Writes the 1-D float64 dataset `name`.
  void vector(const std::string& name, std::span<const double> v);
  /// Writes the 2-D float64 dataset `name` (row-major on disk).
  void matrix(const std::string& name, const Eigen::MatrixXd& m);
  /// Flushes the file and renames it to `path`.
  void commit();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Reads a state file; every error is an InputError naming the file.
class StateFileReader {
 public:
  /// Opens `path` as a state file of `format` and `version`; throws InputError naming the file if it is missing,
  /// not HDF5, damaged, of another format or another version, ending with what the user should do (`remedy`).
  StateFileReader(const std::filesystem::path& path, std::string_view format, long long version, std::string_view what,
                  std::string_view remedy);
  ~StateFileReader();
  StateFileReader(const StateFileReader&) = delete;
  StateFileReader& operator=(const StateFileReader&) = delete;

  /// The string attribute `name`.
  std::string string_attr(const std::string& name) const;
  /// The integer attribute `name`.
  long long int_attr(const std::string& name) const;
  /// The 1-D numeric dataset `name` as float64.
  std::vector<double> vector(const std::string& name) const;
  /// The 2-D numeric dataset `name` as float64.
  Eigen::MatrixXd matrix(const std::string& name) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace specula::store
