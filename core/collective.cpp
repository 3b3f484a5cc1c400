#include "specula/core/collective.h"

#include <algorithm>

#include "specula/core/error.h"

namespace specula {
namespace {

class SingleProcess final : public Collective {
 public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  void allgather(std::span<const double> mine, std::span<double> all) const override {
    if (all.size() != mine.size()) throw UsageError("allgather: output must hold size() * input values");
    std::copy(mine.begin(), mine.end(), all.begin());
  }
};

}  // namespace

const Collective& single_process() {
  static const SingleProcess one;
  return one;
}

void sum_in_rank_order(const Collective& c, std::span<double> values) {
  if (c.size() == 1) return;
  std::vector<double> all(values.size() * std::size_t(c.size()));
  c.allgather(values, all);
  for (std::size_t i = 0; i < values.size(); ++i) {
    double s = all[i];
    for (std::size_t r = 1; r < std::size_t(c.size()); ++r) s += all[r * values.size() + i];
    values[i] = s;
  }
}

Share share_of(const Collective& c, std::size_t n) {
  const auto r = std::size_t(c.rank()), p = std::size_t(c.size());
  return {n * r / p, n * (r + 1) / p};
}

}  // namespace specula
