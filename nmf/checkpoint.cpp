#include "specula/nmf/checkpoint.h"

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"
#include "specula/store/h5.h"

namespace specula::nmf {
namespace h5 = store::h5;
namespace {

constexpr long long kVersion = 1;

void write_history(hid_t loc, const std::string& name, const std::vector<double>& v, std::string_view ctx) {
  h5::write_vector(loc, name, std::span<const double>(v.data(), v.size()), ctx);
}

}  // namespace

void save_checkpoint(const std::filesystem::path& path, const Checkpoint& c) {
  h5::quiet_errors();
  AtomicOutput out(path);
  const std::string ctx = path.string();
  {
    h5::Id file(h5::check(H5Fcreate(out.temp_path().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), ctx,
                          "cannot create checkpoint"));
    h5::write_attr(file, "specula_format", std::string_view("nmf-checkpoint"), ctx);
    h5::write_attr(file, "format_version", kVersion, ctx);
    h5::write_attr(file, "fingerprint", std::string_view(c.fingerprint), ctx);
    h5::write_attr(file, "n", static_cast<long long>(c.n), ctx);
    h5::write_attr(file, "negatives", static_cast<long long>(c.negatives), ctx);
    h5::write_attr(file, "values", static_cast<long long>(c.values), ctx);
    h5::write_attr(file, "restart", static_cast<long long>(c.restart), ctx);
    h5::write_attr(file, "epoch", static_cast<long long>(c.epoch), ctx);
    h5::write_attr(file, "finished_restarts", static_cast<long long>(c.done_bases.size()), ctx);
    h5::write_matrix(file, "gram", c.gram, ctx);
    h5::write_matrix(file, "basis", c.basis, ctx);
    write_history(file, "history", c.history, ctx);
    h5::write_matrix(file, "wave_ctc", c.wave_ctc, ctx);
    h5::write_matrix(file, "wave_ctx", c.wave_ctx, ctx);
    write_history(file, "wave_xx", c.wave_xx, ctx);
    for (std::size_t r = 0; r < c.done_bases.size(); ++r) {
      const std::string p = "restart" + std::to_string(r);
      h5::write_matrix(file, p + "_basis", c.done_bases[r], ctx);
      write_history(file, p + "_history", c.done_histories.at(r), ctx);
      h5::write_attr(file, p + "_converged", static_cast<long long>(c.done_converged.at(r)), ctx);
    }
    h5::check(H5Fflush(file, H5F_SCOPE_GLOBAL), ctx, "cannot write checkpoint");
  }
  out.commit();
}

Checkpoint load_checkpoint(const std::filesystem::path& path) {
  h5::quiet_errors();
  const std::string ctx = path.string();
  if (!std::filesystem::exists(path))
    throw InputError(ctx + ": no checkpoint to resume from (start afresh instead of resuming)");
  if (H5Fis_hdf5(path.c_str()) <= 0)
    throw InputError(ctx + ": not an HDF5 file (a truncated or foreign checkpoint; delete it and start afresh)");
  const hid_t opened = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (opened < 0)
    throw InputError(ctx + ": cannot open the checkpoint (" + h5::last_error() +
                     "); it is truncated or damaged: delete it and start afresh");
  h5::Id file(opened);
  if (!h5::has_attr(file, "specula_format") || h5::read_string_attr(file, "specula_format", ctx) != "nmf-checkpoint")
    throw InputError(ctx + ": not a specula NMF checkpoint");
  const long long version = h5::read_int_attr(file, "format_version", ctx);
  if (version != kVersion)
    throw InputError(ctx + ": checkpoint format version " + std::to_string(version) + ", this specula reads version " +
                     std::to_string(kVersion) + "; start afresh instead of resuming");
  Checkpoint c;
  auto count = [&](const char* name) {
    const long long v = h5::read_int_attr(file, name, ctx);
    if (v < 0) throw InputError(ctx + ": attribute " + std::string(name) + " is negative");
    return std::uint64_t(v);
  };
  c.fingerprint = h5::read_string_attr(file, "fingerprint", ctx);
  c.n = count("n");
  c.negatives = count("negatives");
  c.values = count("values");
  c.restart = std::size_t(count("restart"));
  c.epoch = std::size_t(count("epoch"));
  const std::size_t finished = std::size_t(count("finished_restarts"));
  c.gram = h5::read_matrix(file, "gram", ctx);
  c.basis = h5::read_matrix(file, "basis", ctx);
  c.history = h5::read_vector(file, "history", ctx);
  c.wave_ctc = h5::read_matrix(file, "wave_ctc", ctx);
  c.wave_ctx = h5::read_matrix(file, "wave_ctx", ctx);
  c.wave_xx = h5::read_vector(file, "wave_xx", ctx);
  if (std::size_t(c.wave_ctc.rows()) != c.wave_xx.size() || c.wave_ctc.rows() != c.wave_ctx.rows() ||
      !c.wave_ctc.allFinite() || !c.wave_ctx.allFinite())
    throw InputError(ctx + ": checkpoint wave statistics are malformed; delete it and start afresh");
  if (c.history.size() != c.epoch || finished != c.restart)
    throw InputError(ctx + ": checkpoint is inconsistent (history of " + std::to_string(c.history.size()) +
                     " epochs for " + std::to_string(c.epoch) + "); delete it and start afresh");
  for (std::size_t r = 0; r < finished; ++r) {
    const std::string p = "restart" + std::to_string(r);
    c.done_bases.push_back(h5::read_matrix(file, p + "_basis", ctx));
    c.done_histories.push_back(h5::read_vector(file, p + "_history", ctx));
    c.done_converged.push_back(int(h5::read_int_attr(file, p + "_converged", ctx)));
  }
  if (!c.gram.allFinite() || !c.basis.allFinite() || c.gram.rows() != c.gram.cols() || c.basis.cols() != c.gram.cols())
    throw InputError(ctx + ": checkpoint matrices are malformed; delete it and start afresh");
  return c;
}

}  // namespace specula::nmf
