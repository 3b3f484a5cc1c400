#include <algorithm>
#include <cmath>

#include "specula/acquire/study.h"
#include "specula/core/error.h"

namespace specula::acquire {

Rgb8Sheet study_sheet(const StudyOutput& s, std::size_t per_row) {
  if (per_row == 0) throw UsageError("study_sheet: per_row must be at least 1");
  std::vector<const SphereRender*> panels = {&s.truth, &s.grid_truth};
  for (const auto& r : s.renders) panels.push_back(&r);
  const std::size_t size = s.truth.size, cols = per_row, rows = (panels.size() + cols - 1) / cols;
  double white = 1e-9;
  for (std::size_t p = 0; p < s.truth.value.size(); ++p)
    if (s.truth.covered[p]) white = std::max(white, s.truth.value[p]);
  Rgb8Sheet sheet{cols * size, rows * size, {}};
  sheet.rgb.assign(3 * sheet.width * sheet.height, 32);
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const std::size_t x0 = (i % cols) * size, y0 = (i / cols) * size;
    for (std::size_t p = 0; p < size * size; ++p) {
      if (!panels[i]->covered[p]) continue;
      const double v = std::pow(std::clamp(panels[i]->value[p] / white, 0.0, 1.0), 1 / 2.2);
      const auto g = std::uint8_t(std::lround(255 * v));
      const std::size_t at = 3 * ((y0 + p / size) * sheet.width + x0 + p % size);
      sheet.rgb[at] = sheet.rgb[at + 1] = sheet.rgb[at + 2] = g;
    }
  }
  return sheet;
}

}  // namespace specula::acquire
