#include "specula/nmf/report.h"

#include <omp.h>

#include <nlohmann/json.hpp>
#include <vector>

namespace specula::nmf {
namespace {

using Json = nlohmann::ordered_json;

Json numbers(const std::vector<double>& v) { return Json(v); }
Json numbers(const Eigen::VectorXd& v) { return Json(std::vector<double>(v.data(), v.data() + v.size())); }
Json text(const std::optional<std::string>& s) { return s ? Json(*s) : Json(nullptr); }

Json restarts_json(const NmfResult& r) {
  Json restarts = Json::array();
  for (const auto& rr : r.restarts)
    restarts.push_back({{"rel_error", rr.rel_error},
                        {"epochs", rr.epochs},
                        {"converged", rr.converged},
                        {"mean_angle_deg", rr.mean_angle_deg},
                        {"max_angle_deg", rr.max_angle_deg},
                        {"history", numbers(rr.history)}});
  return restarts;
}

}  // namespace

Json report_json(const LearnedBasis& learned, const RunContext& c) {
  const NmfResult& r = learned.result;
  const RestartResult& best = r.best_result();
  std::vector<double> t;
  for (const auto& e : c.epochs)
    if (e.restart == r.best) t.push_back(e.seconds);
  Json components = Json::array();
  for (Eigen::Index i = 0; i < best.basis.rows(); ++i)
    components.push_back(numbers(Eigen::VectorXd(best.basis.row(i).transpose())));
  Json j;
  j["store"] = c.store;
  j["basis"] = text(c.basis);
  j["output"] = text(c.output);
  j["k"] = learned.basis.k();
  j["n"] = r.n;
  j["bands"] = learned.bands;
  j["rel_error"] = r.rel_error;
  j["svd_bound"] = r.svd_bound;
  j["epochs"] = best.epochs;
  j["converged"] = best.converged;
  j["seconds"] = c.seconds;
  j["restarts"] = restarts_json(r);
  j["best_restart"] = r.best;
  j["history"] = numbers(best.history);
  j["history_seconds"] = numbers(t);
  j["passes"] = r.passes;
  j["resumed"] = r.resumed;
  j["negatives"] = r.negatives;
  j["values"] = r.values;
  j["nnls_unconverged"] = r.nnls_unconverged;
  j["warmup_epochs"] = r.warmup_epochs;
  j["warmup_blocks"] = r.warmup_blocks;
  j["warmup_pass_equivalent"] = r.warmup_pass_equivalent;
  j["weights"] = numbers(r.weights);
  j["components"] = std::move(components);
  j["threads"] = omp_get_max_threads();
  j["ranks"] = c.ranks;
  return j;
}

}  // namespace specula::nmf
