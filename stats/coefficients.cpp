#include "specula/stats/coefficients.h"

#include <omp.h>

#include <algorithm>
#include <cmath>

#include "specula/core/error.h"
#include "specula/core/parallel.h"
#include "specula/core/progress.h"

namespace specula::stats {

double CoefficientMap::relative_error() const { return sum_sq > 0 ? std::sqrt(error.sum_sq / sum_sq) : 0.0; }

std::vector<CoefficientMap> write_coefficient_maps(const store::Store& store, const store::BlockReader& reader,
                                                   const Projector& projector, std::span<const std::string> names,
                                                   const CoefficientMapsOptions& options, store::StoreWriter& writer) {
  const std::vector<std::string>& images = reader.source_names();
  if (names.size() != images.size())
    throw UsageError("write_coefficient_maps: " + std::to_string(names.size()) + " names for " +
                     std::to_string(images.size()) + " images; give one name per image");
  projector.check_wavelengths(reader.wavelengths(), store.label() + ": the images",
                              "learn a basis on the images' grid");
  std::vector<CoefficientMap> maps(images.size());
  for (std::size_t i = 0; i < images.size(); ++i) {
    CoefficientMap& m = maps[i];
    m.name = names[i];
    m.image = images[i];
    const store::ImageInfo info = store.image_info(m.image);
    m.height = info.height;
    m.width = info.width;
    m.valid = info.valid_pixels;
    store::CoefficientsInfo ci;
    ci.image = m.image;
    ci.basis = options.basis_name;
    ci.method = projector.basis().method;
    ci.height = info.height;
    ci.width = info.width;
    ci.k = projector.k();
    ci.valid_pixels = info.valid_pixels;
    ci.chunk_rows = std::max<std::size_t>(1, info.chunk_rows);
    ci.provenance = options.provenance;
    writer.create_coefficients(m.name, ci, projector.basis());
  }

  // Blocks are projected in waves on all threads, then written in block order: the output and the error sums do
  // not depend on the thread count, and memory holds one wave.
  const std::size_t blocks = reader.block_count(), k = projector.k(), bands = reader.bands();
  const std::size_t wave = 4 * std::size_t(std::max(1, omp_get_max_threads()));
  std::vector<store::BlockReader::RawBlock> raw(wave);
  std::vector<std::vector<float>> out(wave);
  std::vector<double> sum_sq(wave);
  std::vector<ProjectionError> errors(wave);
  std::vector<std::uint8_t> ones;
  Progress progress("coefficients on " + options.basis_name, blocks);
  struct Scratch {
    RowMatrixXd x, coef, recon;
    Eigen::VectorXd e2;
  };
  for (std::size_t first = 0; first < blocks; first += wave) {
    const std::size_t n = std::min(wave, blocks - first);
    parallel_for(
        n, [] { return Scratch{}; },
        [&](std::size_t j, Scratch& t) {
          store::BlockReader::RawBlock& r = raw[j];
          reader.read_raw(first + j, r);
          t.x.resize(Eigen::Index(r.valid), Eigen::Index(bands));
          for (std::size_t p = 0, v = 0; p < r.pixels; ++p)
            if (r.is_valid(p))
              t.x.row(Eigen::Index(v++)) =
                  Eigen::Map<const Eigen::RowVectorXf>(r.spectrum(p, bands), Eigen::Index(bands)).cast<double>();
          t.coef.resize(t.x.rows(), Eigen::Index(k));
          t.recon.resize(t.x.rows(), t.x.cols());
          t.e2.resize(t.x.rows());
          projector.project(t.x, t.coef);
          projector.reconstruct(t.coef, t.recon);
          squared_errors(t.x, t.recon, t.e2);
          errors[j] = {};
          for (Eigen::Index i = 0; i < t.e2.size(); ++i) errors[j].add(t.e2[i]);
          sum_sq[j] = t.x.squaredNorm();
          std::vector<float>& c = out[j];
          c.assign(r.pixels * k, 0.0f);
          for (std::size_t p = 0, v = 0; p < r.pixels; ++p)
            if (r.is_valid(p)) {
              for (std::size_t i = 0; i < k; ++i) c[p * k + i] = float(t.coef(Eigen::Index(v), Eigen::Index(i)));
              ++v;
            }
        });
    for (std::size_t j = 0; j < n; ++j) {
      const std::size_t b = first + j;
      CoefficientMap& m = maps[reader.block_source(b)];
      const store::BlockReader::RawBlock& r = raw[j];
      std::span<const std::uint8_t> mask(r.mask);
      if (r.mask.empty()) {
        ones.assign(r.pixels, 1);
        mask = ones;
      }
      writer.write_coefficient_rows(m.name, reader.block_first_row(b), r.pixels / m.width, out[j], mask);
      m.sum_sq += sum_sq[j];
      m.error.merge(errors[j]);
    }
    progress.advance(n);
  }
  return maps;
}

}  // namespace specula::stats
