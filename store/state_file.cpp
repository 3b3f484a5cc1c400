#include "specula/store/state_file.h"

#include <system_error>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"
#include "specula/store/h5.h"

namespace specula::store {

struct StateFileWriter::Impl {
  AtomicOutput out;
  std::string ctx;
  h5::Id file;
  explicit Impl(const std::filesystem::path& path) : out(path), ctx(path.string()) {}
};

StateFileWriter::StateFileWriter(const std::filesystem::path& path, std::string_view format, long long version)
    : impl_(std::make_unique<Impl>(path)) {
  h5::quiet_errors();
  impl_->file = h5::Id(h5::check(H5Fcreate(impl_->out.temp_path().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT),
                                 impl_->ctx, "cannot create the file"));
  attr("specula_format", format);
  attr("format_version", version);
}

StateFileWriter::~StateFileWriter() = default;

void StateFileWriter::attr(const std::string& name, std::string_view value) {
  h5::write_attr(impl_->file, name, value, impl_->ctx);
}

void StateFileWriter::attr(const std::string& name, long long value) {
  h5::write_attr(impl_->file, name, value, impl_->ctx);
}

void StateFileWriter::vector(const std::string& name, std::span<const double> v) {
  h5::write_vector(impl_->file, name, v, impl_->ctx);
}

void StateFileWriter::matrix(const std::string& name, const Eigen::MatrixXd& m) {
  h5::write_matrix(impl_->file, name, m, impl_->ctx);
}

void StateFileWriter::commit() {
  h5::check(H5Fflush(impl_->file, H5F_SCOPE_GLOBAL), impl_->ctx, "cannot write the file");
  impl_->file = h5::Id();
  impl_->out.commit();
}

struct StateFileReader::Impl {
  std::string ctx;
  h5::Id file;
};

StateFileReader::StateFileReader(const std::filesystem::path& path, std::string_view format, long long version,
                                 std::string_view what, std::string_view remedy)
    : impl_(std::make_unique<Impl>()) {
  h5::quiet_errors();
  const std::string& ctx = impl_->ctx = path.string();
  const std::string w(what), fix(remedy);
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(ctx + ": no such " + w + "; " + fix);
  if (H5Fis_hdf5(path.c_str()) <= 0)
    throw InputError(ctx + ": not an HDF5 file (a truncated or foreign " + w + "; " + fix + ")");
  const hid_t opened = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (opened < 0)
    throw InputError(ctx + ": cannot open the " + w + " (" + h5::last_error() +
                     "); it is truncated or damaged: " + fix);
  impl_->file = h5::Id(opened);
  if (!h5::has_attr(impl_->file, "specula_format") ||
      h5::read_string_attr(impl_->file, "specula_format", ctx) != format)
    throw InputError(ctx + ": not a specula " + w);
  const long long v = h5::read_int_attr(impl_->file, "format_version", ctx);
  if (v != version)
    throw InputError(ctx + ": " + w + " format version " + std::to_string(v) + ", this specula reads version " +
                     std::to_string(version) + "; " + fix);
}

StateFileReader::~StateFileReader() = default;

std::string StateFileReader::string_attr(const std::string& name) const {
  return h5::read_string_attr(impl_->file, name, impl_->ctx);
}

long long StateFileReader::int_attr(const std::string& name) const {
  return h5::read_int_attr(impl_->file, name, impl_->ctx);
}

std::vector<double> StateFileReader::vector(const std::string& name) const {
  return h5::read_vector(impl_->file, name, impl_->ctx);
}

Eigen::MatrixXd StateFileReader::matrix(const std::string& name) const {
  return h5::read_matrix(impl_->file, name, impl_->ctx);
}

}  // namespace specula::store
