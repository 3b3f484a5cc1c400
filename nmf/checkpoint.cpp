#include "specula/nmf/checkpoint.h"

#include "specula/core/error.h"
#include "specula/store/state_file.h"

namespace specula::nmf {
namespace {

constexpr long long kVersion = 1;
constexpr std::string_view kFormat = "nmf-checkpoint";

}  // namespace

void save_checkpoint(const std::filesystem::path& path, const Checkpoint& c) {
  store::StateFileWriter file(path, kFormat, kVersion);
  file.attr("fingerprint", std::string_view(c.fingerprint));
  file.attr("n", static_cast<long long>(c.n));
  file.attr("negatives", static_cast<long long>(c.negatives));
  file.attr("values", static_cast<long long>(c.values));
  file.attr("restart", static_cast<long long>(c.restart));
  file.attr("epoch", static_cast<long long>(c.epoch));
  file.attr("finished_restarts", static_cast<long long>(c.done_bases.size()));
  file.matrix("gram", c.gram);
  file.matrix("basis", c.basis);
  file.vector("history", c.history);
  file.matrix("wave_ctc", c.wave_ctc);
  file.matrix("wave_ctx", c.wave_ctx);
  file.vector("wave_xx", c.wave_xx);
  for (std::size_t r = 0; r < c.done_bases.size(); ++r) {
    const std::string p = "restart" + std::to_string(r);
    file.matrix(p + "_basis", c.done_bases[r]);
    file.vector(p + "_history", c.done_histories.at(r));
    file.attr(p + "_converged", static_cast<long long>(c.done_converged.at(r)));
  }
  file.commit();
}

Checkpoint load_checkpoint(const std::filesystem::path& path) {
  const std::string ctx = path.string();
  if (!std::filesystem::exists(path))
    throw InputError(ctx + ": no checkpoint to resume from (start afresh instead of resuming)");
  const store::StateFileReader file(path, kFormat, kVersion, "NMF checkpoint", "delete it and start afresh");
  Checkpoint c;
  auto count = [&](const char* name) {
    const long long v = file.int_attr(name);
    if (v < 0) throw InputError(ctx + ": attribute " + std::string(name) + " is negative");
    return std::uint64_t(v);
  };
  c.fingerprint = file.string_attr("fingerprint");
  c.n = count("n");
  c.negatives = count("negatives");
  c.values = count("values");
  c.restart = std::size_t(count("restart"));
  c.epoch = std::size_t(count("epoch"));
  const std::size_t finished = std::size_t(count("finished_restarts"));
  c.gram = file.matrix("gram");
  c.basis = file.matrix("basis");
  c.history = file.vector("history");
  c.wave_ctc = file.matrix("wave_ctc");
  c.wave_ctx = file.matrix("wave_ctx");
  c.wave_xx = file.vector("wave_xx");
  if (std::size_t(c.wave_ctc.rows()) != c.wave_xx.size() || c.wave_ctc.rows() != c.wave_ctx.rows() ||
      !c.wave_ctc.allFinite() || !c.wave_ctx.allFinite())
    throw InputError(ctx + ": checkpoint wave statistics are malformed; delete it and start afresh");
  if (c.history.size() != c.epoch || finished != c.restart)
    throw InputError(ctx + ": checkpoint is inconsistent (history of " + std::to_string(c.history.size()) +
                     " epochs for " + std::to_string(c.epoch) + "); delete it and start afresh");
  for (std::size_t r = 0; r < finished; ++r) {
    const std::string p = "restart" + std::to_string(r);
    c.done_bases.push_back(file.matrix(p + "_basis"));
    c.done_histories.push_back(file.vector(p + "_history"));
    c.done_converged.push_back(int(file.int_attr(p + "_converged")));
  }
  if (!c.gram.allFinite() || !c.basis.allFinite() || c.gram.rows() != c.gram.cols() || c.basis.cols() != c.gram.cols())
    throw InputError(ctx + ": checkpoint matrices are malformed; delete it and start afresh");
  return c;
}

}  // namespace specula::nmf
