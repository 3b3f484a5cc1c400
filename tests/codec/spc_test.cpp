#include "specula/codec/spc.h"

#include <gtest/gtest.h>
#include <omp.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>

#include "grid_fixture.h"
#include "specula/codec/diff.h"
#include "specula/codec/environment.h"
#include "specula/codec/spectral_grid.h"
#include "specula/codec/uplift.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/brdf_models.h"
#include "specula/core/error.h"
#include "specula/core/illuminant.h"
#include "test_support.h"

namespace specula::codec {
namespace {

constexpr std::size_t N = brdf::kMerlCells;
const WavelengthGrid& kGrid = test::kCodecBands;
using test::grid_of;

Eigen::VectorXd ramp(double a, double b) { return Eigen::VectorXd::LinSpaced(Eigen::Index(kGrid.size()), a, b); }

const store::Grid& ward() {
  static const store::Grid g =
      grid_of(brdf::Ward(kGrid, ramp(0.05, 0.4), ramp(0.3, 0.05), Eigen::VectorXd::Constant(7, 0.1)));
  return g;
}
const store::Grid& torrance() {
  static const store::Grid g =
      grid_of(brdf::TorranceSparrow(kGrid, Eigen::VectorXd::Constant(7, 0.15), ramp(1.55, 1.45), ramp(0.5, 0.1)));
  return g;
}

// The bound of spc.h, checked value by value: |x' - x| <= |m' - m| |r'_b| + m (E + |r_b - r_k,b|), with
// |m' - m| <= E (m + s); float32 output adds a relative 1e-6.
void expect_within_bound(const store::Grid& in, const SpcBasis& basis, double e, const SpcBoundedOptions& o) {
  SpcReport rep;
  const auto bytes = encode_spc(in, basis, o, &rep);
  const store::Grid out = decode_spc(bytes, "test.spc");
  ASSERT_EQ(out.brdf.size(), in.brdf.size());
  EXPECT_LE(rep.max_quantisation_error, e * (1 + 1e-9));
  const double s = rep.magnitude_scale;
  const std::size_t b = in.bands();
  std::size_t checked = 0;
  for (std::size_t c = 0; c < N; c += 7) {
    if (in.brdf[c] < 0) {
      EXPECT_LT(out.brdf[c], 0) << c;
      continue;
    }
    Eigen::VectorXd x(static_cast<Eigen::Index>(b)), y(static_cast<Eigen::Index>(b));
    for (std::size_t k = 0; k < b; ++k)
      x[Eigen::Index(k)] = in.brdf[k * N + c], y[Eigen::Index(k)] = out.brdf[k * N + c];
    const double m = x.mean(), mq = y.mean();
    if (m == 0) {
      EXPECT_EQ(y.norm(), 0) << c;
      continue;
    }
    const Eigen::VectorXd r = x / m;
    const Eigen::VectorXd rk = basis.rows.transpose() * (basis.rows * r);
    const double dm = e * (m + s) * (1 + 1e-9);
    for (std::size_t k = 0; k < b; ++k) {
      const double rb = std::abs(rk[Eigen::Index(k)]) + e;  // |r'_b| <= |r_k,b| + E
      const double bound = dm * rb + m * (e + std::abs(r[Eigen::Index(k)] - rk[Eigen::Index(k)]));
      ASSERT_LE(std::abs(y[Eigen::Index(k)] - x[Eigen::Index(k)]), bound + 1e-6 * std::abs(x[Eigen::Index(k)]) + 1e-30)
          << "cell " << c << " band " << k << " m " << m << " m' " << mq;
    }
    ++checked;
  }
  EXPECT_GT(checked, 10000u);
}

TEST(Spc, ALambertianGridOnItsOwnShapeIsReproducedWithinTheMagnitudeBound) {
  const store::Grid g = grid_of(brdf::Lambertian(kGrid, ramp(0.1, 0.6)));
  const SpcBasis basis = self_basis(g, 1);
  for (const double e : {1e-4, 1e-2}) expect_within_bound(g, basis, e, {.max_error = e});
}

TEST(Spc, TheStatedBoundHoldsOnWardAndTorranceSparrowGrids) {
  for (const store::Grid* g : {&ward(), &torrance()}) {
    expect_within_bound(*g, self_basis(*g, 3), 0.01, {.max_error = 0.01});
    expect_within_bound(*g, self_basis(*g, 2), 0.003, {.max_error = 0.003, .magnitude_scale = 0.5});
  }
}

TEST(Spc, SmallerErrorsCostMoreBytes) {
  const SpcBasis basis = self_basis(ward(), 3);
  std::size_t previous = 0;
  for (const double e : {0.1, 0.01, 0.001}) {
    SpcReport rep;
    const auto bytes = encode_spc(ward(), basis, {.max_error = e}, &rep);
    EXPECT_GT(bytes.size(), previous) << e;
    EXPECT_EQ(rep.output_bytes, bytes.size());
    EXPECT_EQ(rep.input_bytes, 7u * N * 8);
    previous = bytes.size();
  }
}

TEST(Spc, BytesDoNotDependOnTheThreadCount) {
  const SpcBasis basis = self_basis(torrance(), 3);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto one = encode_spc(torrance(), basis, {.max_error = 0.01});
  const store::Grid d1 = decode_spc(one, "one");
  omp_set_num_threads(2);
  const auto two = encode_spc(torrance(), basis, {.max_error = 0.01});
  const store::Grid d2 = decode_spc(two, "two");
  omp_set_num_threads(threads);
  EXPECT_EQ(one, two);
  EXPECT_EQ(d1.brdf, d2.brdf);
}

TEST(Spc, ALearnedBasisIsOrthonormalisedOverItsMeanAndComponents) {
  store::Basis pca;
  pca.method = "pca";
  pca.wavelengths = kGrid;
  pca.mean = ramp(0.2, 0.5);
  pca.components = Eigen::MatrixXd::Zero(2, 7);
  pca.components(0, 0) = 1;
  pca.components(1, 6) = 1;
  const SpcBasis b = coding_basis(pca, 3, "db.h5:pca");
  EXPECT_LT((b.rows * b.rows.transpose() - Eigen::MatrixXd::Identity(3, 3)).norm(), 1e-12);
  // The mean lies in the span.
  EXPECT_LT((b.rows.transpose() * (b.rows * pca.mean) - pca.mean).norm(), 1e-12);
  EXPECT_THROW(coding_basis(pca, 4, "db.h5:pca"), UsageError);
  store::Basis nmf = pca;
  nmf.method = "nmf";
  EXPECT_EQ(coding_basis(nmf, 2, "db.h5:nmf").k(), 2u);
  EXPECT_THROW(coding_basis(nmf, 3, "db.h5:nmf"), UsageError);
}

// A flat learned basis cannot express a coloured Lambertian's shape; one fitted extra spectrum can, exactly.
TEST(Spc, AnAugmentedLearnedBasisFitsAShapeOutsideItsSpan) {
  store::Basis flat;
  flat.method = "nmf";
  flat.wavelengths = kGrid;
  flat.components = Eigen::MatrixXd::Ones(1, 7);
  const SpcBasis learned = coding_basis(flat, 1, "db.h5:flat");
  const store::Grid g = grid_of(brdf::Lambertian(kGrid, ramp(0.1, 0.6)));
  SpcReport before, after;
  encode_spc(g, learned, {.max_error = 0.001}, &before);
  const SpcBasis more = augment_basis(learned, g, 1);
  EXPECT_EQ(more.k(), 2u);
  EXPECT_EQ(more.reference, "db.h5:flat+1");
  EXPECT_LT((more.rows * more.rows.transpose() - Eigen::MatrixXd::Identity(2, 2)).norm(), 1e-12);
  EXPECT_LT((more.rows.row(0) - learned.rows.row(0)).norm(), 1e-12);  // the learned spectrum is kept
  encode_spc(g, more, {.max_error = 0.001}, &after);
  EXPECT_GT(before.max_shape_residual, 0.1);
  EXPECT_LT(after.max_shape_residual, 1e-9);
  EXPECT_THROW(augment_basis(learned, g, 7), UsageError);
  EXPECT_EQ(augment_basis(learned, g, 0).k(), 1u);
}

TEST(Spc, MismatchedWavelengthsAndBadOptionsAreRefused) {
  SpcBasis other = self_basis(ward(), 2);
  other.wavelengths = WavelengthGrid::range(400, 700, 50);
  other.reference = "db.h5:pca";
  const std::string text = test::input_error_text([&] { encode_spc(ward(), other, SpcBoundedOptions{}); });
  EXPECT_NE(text.find("db.h5:pca"), std::string::npos) << text;
  EXPECT_NE(text.find("420-720"), std::string::npos) << text;
  const SpcBasis basis = self_basis(ward(), 2);
  EXPECT_THROW(encode_spc(ward(), basis, {.max_error = 0}), UsageError);
  EXPECT_THROW(encode_spc(ward(), basis, {.max_error = std::nan("")}), UsageError);
  EXPECT_THROW(encode_spc(ward(), basis, {.max_error = 0.01, .zstd_level = 0}), UsageError);
  EXPECT_THROW(self_basis(ward(), 0), UsageError);
  store::Grid bad = ward();
  bad.brdf[12345] = std::nanf("");
  EXPECT_THROW(encode_spc(bad, basis, SpcBoundedOptions{}), InputError);
}

std::vector<std::uint8_t> with_crc(std::vector<std::uint8_t> b) {
  const uLong crc = crc32(crc32(0L, Z_NULL, 0), b.data(), uInt(b.size() - 4));
  const auto c = std::uint32_t(crc);
  std::memcpy(b.data() + b.size() - 4, &c, 4);
  return b;
}

TEST(Spc, CorruptOrTruncatedFilesFailCleanly) {
  const auto good = encode_spc(ward(), self_basis(ward(), 2), {.max_error = 0.01});
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 200; ++trial) {
    auto b = good;
    b[rng() % b.size()] ^= std::uint8_t(1u << (rng() % 8));
    EXPECT_THROW(decode_spc(b, "bad.spc"), InputError) << trial;
  }
  for (std::size_t n :
       {std::size_t(0), std::size_t(7), std::size_t(20), std::size_t(100), good.size() / 2, good.size() - 1}) {
    const std::vector<std::uint8_t> b(good.begin(), good.begin() + std::ptrdiff_t(n));
    EXPECT_THROW(decode_spc(b, "short.spc"), InputError) << n;
  }
  // Consistent CRC but impossible fields: still one clear error each.
  auto newer = good;
  newer[8] = 99;
  EXPECT_NE(test::input_error_text([&] { decode_spc(newer, "new.spc"); }).find("version 99"), std::string::npos);
  auto k_too_big = good;
  k_too_big[16] = 200;  // k > bands
  EXPECT_NE(test::input_error_text([&] { decode_spc(with_crc(k_too_big), "k.spc"); }).find("k = 200"),
            std::string::npos);
  auto bad_step = good;
  const double negative = -1;
  std::memcpy(bad_step.data() + 28, &negative, 8);  // magnitude scale
  EXPECT_NE(test::input_error_text([&] { decode_spc(with_crc(bad_step), "s.spc"); }).find("magnitude scale"),
            std::string::npos);
  auto trailing = good;
  trailing.insert(trailing.end() - 4, 3, 0);
  EXPECT_NE(test::input_error_text([&] { decode_spc(with_crc(trailing), "t.spc"); }).find("unexpected bytes"),
            std::string::npos);
  EXPECT_NE(test::input_error_text([&] { decode_spc(std::vector<std::uint8_t>(40, 7), "x.spc"); }).find("magic"),
            std::string::npos);
}

// ---- Format 2: the transform coder ----

SpcTransformOptions transform(double step) {
  SpcTransformOptions o;
  o.step = step;
  return o;
}

// RMS over valid cells and bands of decoded minus original, computed here rather than taken from the report.
double rms_between(const store::Grid& a, const store::Grid& b) {
  double sq = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.brdf.size(); ++i)
    if (a.brdf[i] >= 0) sq += double(b.brdf[i] - a.brdf[i]) * (b.brdf[i] - a.brdf[i]), ++n;
  return std::sqrt(sq / double(n));
}

TEST(SpcTransform, CoarserStepsCostFewerBytesAndMoreError) {
  const SpcBasis basis = self_basis(torrance(), 3);
  std::size_t previous = SIZE_MAX;
  double previous_rms = 0;
  for (const double step : {0.001, 0.01, 0.1}) {
    SpcReport rep;
    const auto bytes = encode_spc(torrance(), basis, transform(step), &rep);
    EXPECT_EQ(bytes[8], 3) << "format version (the default grazing factor)";
    EXPECT_EQ(rep.output_bytes, bytes.size());
    const store::Grid back = decode_spc(bytes, "t.spc");
    const double rms = rms_between(torrance(), back);
    EXPECT_NEAR(rep.rms_error, rms, 1e-6 * rms + 1e-12) << step;
    EXPECT_LT(bytes.size(), previous) << step;
    EXPECT_GT(rms, previous_rms) << step;
    previous = bytes.size();
    previous_rms = rms;
  }
}

// With a fine step the transform path is close to exact where a rendering looks (cos-weighted relative RMS).
TEST(SpcTransform, AFineStepReproducesTheGrid) {
  for (const store::Grid* g : {&ward(), &torrance()}) {
    const store::Grid back = decode_spc(encode_spc(*g, self_basis(*g, 3), transform(1e-4)), "fine.spc");
    const GridDiff d = diff_grids(*g, back, default_environment(kGrid), {.size = 32});
    EXPECT_EQ(d.only_a + d.only_b, 0u);
    EXPECT_LT(d.rel_rms_cos, 2e-3);
    EXPECT_LT(d.de00_max, 0.05);
  }
}

// The specular factor spends bits on small half-angles: with it the error there falls, far from it nothing changes
// much, measured cell by cell on the decoded grids.
TEST(SpcTransform, TheSpecularRegionIsCodedFiner) {
  const SpcBasis basis = self_basis(torrance(), 3);
  auto rms_by_theta_h = [&](double factor) {
    SpcTransformOptions o = transform(0.2);
    o.specular_factor = factor;
    const store::Grid back = decode_spc(encode_spc(torrance(), basis, o), "s.spc");
    std::array<double, 2> sq{}, ref{};
    for (std::size_t c = 0; c < N; ++c) {
      const int h = brdf::merl_cell(c).theta_h;
      if ((h >= 20 && h < 70) || torrance().brdf[c] < 0) continue;
      for (std::size_t b = 0; b < 7; ++b) {
        const double x = torrance().brdf[b * N + c], e = back.brdf[b * N + c] - x;
        sq[h < 20 ? 0 : 1] += e * e;
        ref[h < 20 ? 0 : 1] += x * x;
      }
    }
    return std::array<double, 2>{std::sqrt(sq[0] / ref[0]), std::sqrt(sq[1] / ref[1])};
  };
  const auto plain = rms_by_theta_h(1), specular = rms_by_theta_h(0.25);
  EXPECT_LT(specular[0], 0.6 * plain[0]);
  EXPECT_NEAR(specular[1], plain[1], 0.1 * plain[1]);
  SpcTransformOptions bad = transform(0.1);
  bad.specular_factor = 0;
  EXPECT_THROW(encode_spc(torrance(), basis, bad), UsageError);
}

// Formats 2 (grazing factor 1) and 3 (the default grazing factor) alike.
TEST(SpcTransform, BytesAndDecodingDoNotDependOnTheThreadCount) {
  const SpcBasis basis = self_basis(ward(), 3);
  const int threads = omp_get_max_threads();
  for (const double grazing : {1.0, 2.0}) {
    SpcTransformOptions o = transform(0.02);
    o.grazing_factor = grazing;
    omp_set_num_threads(1);
    const auto one = encode_spc(ward(), basis, o);
    const SpcCoefficients c1 = decode_spc_coefficients(one, "one");
    omp_set_num_threads(2);
    const auto two = encode_spc(ward(), basis, o);
    const SpcCoefficients c2 = decode_spc_coefficients(two, "two");
    omp_set_num_threads(threads);
    EXPECT_EQ(one[8], grazing == 1 ? 2 : 3);
    EXPECT_EQ(one, two);
    EXPECT_EQ(c1.values, c2.values);
    EXPECT_EQ(c1.valid, c2.valid);
  }
}

// The grazing factor (format 3) changes the step with theta_d only: measured cell by cell on the decoded grids, a
// factor of 4 leaves the error at small theta_d about as it was and raises it at grazing theta_d; 1 writes format 2.
TEST(SpcTransform, TheGrazingFactorCodesGrazingThetaDCoarser) {
  const SpcBasis basis = self_basis(torrance(), 3);
  auto rms_by_theta_d = [&](double factor, std::uint8_t version) {
    SpcTransformOptions o = transform(0.2);
    o.grazing_factor = factor;
    const auto bytes = encode_spc(torrance(), basis, o);
    EXPECT_EQ(bytes[8], version);
    EXPECT_EQ(spc_format_version(bytes, "g.spc"), version);
    const store::Grid back = decode_spc(bytes, "g.spc");
    std::array<double, 2> sq{}, ref{};
    for (std::size_t c = 0; c < N; ++c) {
      const int d = brdf::merl_cell(c).theta_d;
      if ((d >= 12 && d < 70) || torrance().brdf[c] < 0) continue;
      for (std::size_t b = 0; b < 7; ++b) {
        const double x = torrance().brdf[b * N + c], e = back.brdf[b * N + c] - x;
        sq[d < 12 ? 0 : 1] += e * e;
        ref[d < 12 ? 0 : 1] += x * x;
      }
    }
    return std::array<double, 2>{std::sqrt(sq[0] / ref[0]), std::sqrt(sq[1] / ref[1])};
  };
  const auto plain = rms_by_theta_d(1, 2), grazing = rms_by_theta_d(4, 3);
  EXPECT_NEAR(grazing[0], plain[0], 0.25 * plain[0]);
  EXPECT_GT(grazing[1], 1.5 * plain[1]);
  for (const double bad : {0.0, 0.05, 17.0, std::nan("")}) {
    SpcTransformOptions o = transform(0.1);
    o.grazing_factor = bad;
    EXPECT_THROW(encode_spc(torrance(), basis, o), UsageError) << bad;
  }
  // A format-3 file is strict about its field: a factor of 1 (format 2's) or out of range is refused.
  SpcTransformOptions o = transform(0.1);
  o.grazing_factor = 4;
  const auto good = encode_spc(ward(), self_basis(ward(), 2), o);
  const std::array<double, 2> extent_and_factor{45, 4};  // the specular extent, then the grazing factor
  const auto* pattern = reinterpret_cast<const std::uint8_t*>(extent_and_factor.data());
  const auto at = std::search(good.begin(), good.end(), pattern, pattern + 16) - good.begin() + 8;
  ASSERT_LT(std::size_t(at), good.size());
  for (const double bad : {1.0, 20.0}) {
    auto b = good;
    std::memcpy(b.data() + at, &bad, 8);
    EXPECT_NE(test::input_error_text([&] { decode_spc(with_crc(b), "g.spc"); }).find("grazing factor"),
              std::string::npos);
  }
}

// A format-2 file written before format 3 existed (tests/codec/data/rp-k3-v2.spc: `specula synth-brdf red-plastic
// --wavelengths 400:700:50`, then `encode --basis self -k 3 --step 0.05`) still decodes, to what the coder now
// writes at grazing factor 1, which is format 2 again.
TEST(SpcTransform, FormatTwoFilesStillDecode) {
  std::ifstream f(SPECULA_SOURCE_DIR "/tests/codec/data/rp-k3-v2.spc", std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  ASSERT_EQ(bytes[8], 2);
  const SpcCoefficients old = decode_spc_coefficients(bytes, "rp-k3-v2.spc");
  const store::Grid grid = grid_of(*brdf::make_material("red-plastic", WavelengthGrid::range(400, 700, 50)));
  SpcTransformOptions o = transform(0.05);
  o.grazing_factor = 1;
  const auto now = encode_spc(grid, self_basis(grid, 3), o);
  EXPECT_EQ(now[8], 2);
  const SpcCoefficients fresh = decode_spc_coefficients(now, "now.spc");
  EXPECT_EQ(old.valid, fresh.valid);
  // The file was written by a Release build; another optimisation level (the sanitizer build's -O1) fits a basis that
  // differs in the last bits, and its coefficients with it, so the old file is judged by what it decodes to: as close
  // to the material as a fresh encoding at the same settings.
  const store::Grid a = decode_spc(bytes, "rp-k3-v2.spc"), b = decode_spc(now, "now.spc");
  ASSERT_EQ(a.brdf.size(), grid.brdf.size());
  ASSERT_EQ(b.brdf.size(), grid.brdf.size());
  double ea = 0, eb = 0, norm = 0;
  for (std::size_t i = 0; i < grid.brdf.size(); ++i) {
    if (grid.brdf[i] < 0) continue;
    ea += std::pow(double(a.brdf[i]) - grid.brdf[i], 2);
    eb += std::pow(double(b.brdf[i]) - grid.brdf[i], 2);
    norm += std::pow(double(grid.brdf[i]), 2);
  }
  EXPECT_GT(norm, 0);
  EXPECT_LT(std::sqrt(ea / norm), 1.05 * std::sqrt(eb / norm) + 1e-6);
  EXPECT_LT(std::sqrt(ea / norm), 0.1);
}

// Every kind of validity comes back exactly: all cells, the horizon rule, and arbitrary holes.
// A cell without data in the grid has none in the decoding, and its coefficients are 0 (spc.h). The decoder sizes the
// form unwritten and zeroes those cells: a Release build gets zeroed pages from the kernel either way, but under
// AddressSanitizer a fresh allocation's first bytes are 0xbe, so cell 0 of `holes` fails if the zeroing is lost.
TEST(SpcTransform, CellsWithoutDataStayWithoutAndHoldZeroCoefficients) {
  store::Grid all = ward();
  for (float& v : all.brdf) v = std::max(v, 0.0f);
  store::Grid holes = ward();
  std::mt19937 rng(3);
  for (int i = 0; i < 20000; ++i) holes.brdf[rng() % N] = -1;  // band 0 of random cells
  holes.brdf[0] = -1;
  for (const store::Grid* g :
       {static_cast<const store::Grid*>(&all), &ward(), static_cast<const store::Grid*>(&holes)}) {
    const SpcCoefficients c = decode_spc_coefficients(encode_spc(*g, self_basis(*g, 2), transform(0.05)), "v.spc");
    std::size_t mismatches = 0, nonzero = 0;
    for (std::size_t cell = 0; cell < N; ++cell) {
      bool valid = true;
      for (std::size_t b = 0; b < 7; ++b) valid &= g->brdf[b * N + cell] >= 0;
      mismatches += valid != (c.valid[cell] == 1);
      if (c.valid[cell]) continue;
      for (std::size_t j = 0; j < c.k(); ++j) nonzero += c.values[cell * c.k() + j] != 0.0f;
    }
    EXPECT_EQ(mismatches, 0u);
    EXPECT_EQ(nonzero, 0u);
    if (g == &holes) {
      EXPECT_EQ(c.valid[0], 0);
    }
  }
}

TEST(SpcTransform, IrregularWavelengthsAreKept) {
  const WavelengthGrid irregular({420, 433, 470, 561.5, 600, 652, 720});
  store::Grid g = ward();
  g.wavelengths = irregular;
  const auto bytes = encode_spc(g, self_basis(g, 2), transform(0.05));
  EXPECT_TRUE(decode_spc(bytes, "w.spc").wavelengths.approx_equal(irregular, 0));
  EXPECT_TRUE(spc_basis(bytes, "w.spc").wavelengths.approx_equal(irregular, 0));
}

TEST(SpcTransform, CorruptOrTruncatedFilesFailCleanly) {
  store::Grid all = ward();
  for (float& v : all.brdf) v = std::max(v, 0.0f);
  const auto good = encode_spc(all, self_basis(all, 2), transform(0.02));
  std::mt19937_64 rng(9);
  for (int trial = 0; trial < 100; ++trial) {
    auto b = good;
    b[rng() % b.size()] ^= std::uint8_t(1u << (rng() % 8));
    EXPECT_THROW(decode_spc(b, "bad.spc"), InputError) << trial;
  }
  for (std::size_t n : {std::size_t(10), std::size_t(40), good.size() / 2, good.size() - 1}) {
    const std::vector<std::uint8_t> b(good.begin(), good.begin() + std::ptrdiff_t(n));
    EXPECT_THROW(decode_spc(b, "short.spc"), InputError) << n;
  }
  // Fields with a consistent CRC: magic 8, version 4, bands 4, k 4, scale 8, s 8, then the wavelength kind at 36
  // (0: first and step, 16 bytes), the float basis, three strings (32-bit length, bytes), the valid count and the
  // validity kind (0: all valid), then the level count.
  auto field = [&](std::size_t at, std::uint8_t value, const std::string& expect) {
    auto b = good;
    b[at] = value;
    const std::string text = test::input_error_text([&] { decode_spc(with_crc(b), "f.spc"); });
    EXPECT_NE(text.find(expect), std::string::npos) << text;
  };
  std::size_t validity = 37 + 16 + 4 * 2 * 7;
  for (int i = 0; i < 3; ++i) {
    std::uint32_t n;
    std::memcpy(&n, good.data() + validity, 4);
    validity += 4 + n;
  }
  validity += 8;
  ASSERT_EQ(good[validity], 0);
  field(36, 7, "wavelength kind 7");
  field(validity, 9, "validity kind 9");
  field(validity + 1, 9, "9 levels");
  auto stream_cut = good;
  stream_cut.erase(stream_cut.end() - 40, stream_cut.end() - 4);
  EXPECT_THROW(decode_spc(with_crc(stream_cut), "cut.spc"), InputError);
}

// A format-1 file written before format 2 existed (a 7-band green matte Lambertian, self basis k = 1, max error
// 0.01) still decodes, to the analytic material within its bound.
TEST(SpcTransform, FormatOneFilesStillDecode) {
  std::ifstream f(SPECULA_SOURCE_DIR "/tests/codec/data/green-matte-7band-v1.spc", std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  ASSERT_EQ(bytes[8], 1);
  const store::Grid back = decode_spc(bytes, "green-matte-7band-v1.spc");
  const store::Grid truth = grid_of(*brdf::make_material("green-matte", kGrid));
  std::size_t checked = 0;
  for (std::size_t cell = 0; cell < N; ++cell) {
    double m = 0;
    for (std::size_t b = 0; b < 7; ++b) m += truth.brdf[b * N + cell] / 7.0;
    for (std::size_t b = 0; b < 7; ++b) {
      const std::size_t i = b * N + cell;
      ASSERT_EQ(back.brdf[i] < 0, truth.brdf[i] < 0) << i;
      if (truth.brdf[i] < 0) continue;
      // |x' - x| <= |m' - m| |r'_b| + m E, with |m' - m| <= E (m + s), s = m / 10 for a Lambertian, and the shape
      // in the basis's span (spc.h).
      ASSERT_LE(std::abs(back.brdf[i] - truth.brdf[i]), 0.0111 * truth.brdf[i] * 1.0101 + 0.0101 * m) << i;
      ++checked;
    }
  }
  EXPECT_GT(checked, 7000000u);
}

}  // namespace
}  // namespace specula::codec
