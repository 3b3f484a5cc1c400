#include "specula/codec/nbrdf.h"

#include <algorithm>
#include <cmath>

#include "specula/codec/spectral_grid.h"
#include "specula/core/error.h"
#include "specula/core/parallel.h"

namespace specula::codec {
namespace {

using store::NbrdfWeights;

// One dense layer: out = kernel^T in + bias, kernel row-major (inputs x outputs) as Keras stores it.
template <int In, int Out>
void dense(const std::vector<float>& kernel, const std::vector<float>& bias, const double* in, double* out) {
  for (int o = 0; o < Out; ++o) out[o] = bias[std::size_t(o)];
  for (int i = 0; i < In; ++i)
    for (int o = 0; o < Out; ++o) out[o] += in[i] * double(kernel[std::size_t(i * Out + o)]);
}

}  // namespace

Eigen::Vector3d nbrdf_value(const NbrdfWeights& w, const Eigen::Vector3d& h, const Eigen::Vector3d& d) {
  constexpr int kI = NbrdfWeights::kInputs, kH = NbrdfWeights::kHidden, kO = NbrdfWeights::kOutputs;
  const double x[kI] = {h.x(), h.y(), h.z(), d.x(), d.y(), d.z()};
  double a[kH], b[kH], y[kO];
  dense<kI, kH>(w.kernel1, w.bias1, x, a);
  for (double& v : a) v = std::max(v, 0.0);
  dense<kH, kH>(w.kernel2, w.bias2, a, b);
  for (double& v : b) v = std::max(v, 0.0);
  dense<kH, kO>(w.kernel3, w.bias3, b, y);
  return {std::expm1(y[0]), std::expm1(y[1]), std::expm1(y[2])};
}

MerlBrdf nbrdf_to_merl(const NbrdfWeights& w, NbrdfGridReport* report) {
  MerlBrdf out;
  constexpr std::size_t kRow = std::size_t(brdf::kMerlThetaD) * brdf::kMerlPhiD;  // one theta_h row of cells
  std::vector<NbrdfGridReport> rows(brdf::kMerlThetaH);
  parallel_for(rows.size(), [&](std::size_t i) {
    for (std::size_t cell = i * kRow; cell < (i + 1) * kRow; ++cell) {
      const brdf::MerlCell c = brdf::merl_cell(cell);
      if (!brdf::merl_cell_valid(c)) continue;
      const brdf::HalfDiff hd = brdf::merl_cell_centre(c);
      Eigen::Vector3d rgb =
          nbrdf_value(w, brdf::direction(hd.theta_h, hd.phi_h), brdf::direction(hd.theta_d, hd.phi_d));
      for (int k = 0; k < 3; ++k)
        if (!(rgb[k] >= 0)) {
          rgb[k] = 0;
          ++rows[i].clamped;
        }
      out.set(cell, rgb);
      ++rows[i].cells;
    }
  });
  if (report) {
    *report = {};
    for (const auto& r : rows) report->cells += r.cells, report->clamped += r.clamped;
  }
  return out;
}

std::vector<std::filesystem::path> nbrdf_files(std::span<const std::filesystem::path> inputs) {
  std::vector<std::filesystem::path> files;
  for (const auto& in : inputs) {
    std::error_code ec;
    if (std::filesystem::is_directory(in, ec)) {
      std::vector<std::filesystem::path> found;
      for (const auto& e : std::filesystem::directory_iterator(in))
        if (e.is_regular_file() && e.path().extension() == ".h5") found.push_back(e.path());
      if (found.empty()) throw InputError(in.string() + ": the directory holds no .h5 file (NBRDF weights)");
      std::sort(found.begin(), found.end());
      files.insert(files.end(), found.begin(), found.end());
    } else if (std::filesystem::is_regular_file(in, ec)) {
      files.push_back(in);
    } else {
      throw InputError(in.string() + ": no such file or directory");
    }
  }
  return files;
}

std::vector<std::string> import_nbrdf(store::StoreWriter& writer, std::span<const std::filesystem::path> files,
                                      const NbrdfImportOptions& o) {
  if (!o.name.empty() && files.size() > 1)
    throw UsageError("import: the `name` option names one grid, but " + std::to_string(files.size()) +
                     " NBRDF files were given; leave it out to name each grid after its file");
  if (std::size_t(o.illuminant.size()) != o.wavelengths.size())
    throw UsageError("import: the illuminant needs one value per wavelength");
  const Uplift uplift(rgb_weights(o.wavelengths, o.illuminant), o.alpha);
  std::vector<std::string> names;
  std::vector<store::NbrdfWeights> weights;
  for (const auto& f : files) {  // every file read and every name checked before anything is written
    names.push_back(o.name.empty() ? f.stem().string() : o.name);
    store::validate_name(names.back(), "grid");
    weights.push_back(store::read_nbrdf(f));
  }
  std::vector<std::string> lines;
  for (std::size_t i = 0; i < files.size(); ++i) {
    NbrdfGridReport rgb_report;
    const MerlBrdf rgb = nbrdf_to_merl(weights[i], &rgb_report);
    UpliftReport up;
    store::Grid g = uplift_merl(rgb, o.wavelengths, uplift, UpliftMethod::nonnegative, &up);
    g.provenance.source_file = files[i].string();
    g.provenance.importer = "nbrdf";
    writer.add_grid(names[i], g);
    lines.push_back(files[i].string() + " -> grid " + names[i] + ": NBRDF at " + std::to_string(rgb_report.cells) +
                    " cell centres (" + std::to_string(rgb_report.clamped) +
                    " negative channel values set to 0), uplifted to " + o.wavelengths.describe());
  }
  return lines;
}

}  // namespace specula::codec
