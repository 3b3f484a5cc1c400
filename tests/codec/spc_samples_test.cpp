// .spc format 4 (scattered samples and their resampling rule) against independent answers: the grid the exact samples
// resample to, the suite's separately written evaluation of the decoded file, and the container's checks.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstring>
#include <random>

#include "grid_fixture.h"
#include "specula/codec/spc.h"
#include "specula/codec/spc_detail.h"
#include "specula/codec/spc_target.h"
#include "specula/core/brdf_materials.h"
#include "specula/core/brdf_models.h"
#include "specula/core/error.h"
#include "suite_reference.h"

namespace specula::codec {
namespace {

const WavelengthGrid& kGrid = test::kCodecBands;

// n samples of an analytic material at goniometer-like positions (a few distinct polar angles, many azimuths), as a
// measured set: each row's angles and the material's value there.
struct Samples {
  std::vector<double> angles;
  std::vector<float> values;
  SpcSampleSet set() const { return {kGrid, angles, values, "1/sr", 1}; }
};

Samples gonio_samples(const std::string& material, std::size_t n, std::uint64_t seed) {
  const auto brdf = brdf::make_material(material, kGrid);
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> ti(1, 8), to(0, 9), po(0, 179);
  Samples s;
  std::vector<double> v(kGrid.size());
  for (std::size_t i = 0; i < n; ++i) {
    const brdf::StdAngles a{0.17 * ti(rng), 0.0, 0.15 * to(rng), -3.1 + 0.0349 * po(rng)};
    s.angles.insert(s.angles.end(), {a.theta_i, a.phi_i, a.theta_o, a.phi_o});
    brdf->eval(a, v);
    for (const double x : v) s.values.push_back(float(x));
  }
  return s;
}

// Cells valid in a and in b, and the largest |a - b| / (|a| + floor) over them and every band.
struct Agreement {
  std::size_t both = 0, only_a = 0, only_b = 0;
  double worst = 0;
};

Agreement agreement(const store::Grid& a, const store::Grid& b, double floor) {
  Agreement r;
  const std::size_t bands = a.bands();
  for (std::size_t c = 0; c < brdf::kMerlCells; ++c) {
    const bool va = a.brdf[c] >= 0, vb = b.brdf[c] >= 0;
    r.only_a += va && !vb;
    r.only_b += vb && !va;
    if (!(va && vb)) continue;
    ++r.both;
    for (std::size_t q = 0; q < bands; ++q) {
      const double x = a.brdf[q * brdf::kMerlCells + c], y = b.brdf[q * brdf::kMerlCells + c];
      r.worst = std::max(r.worst, std::abs(x - y) / (std::abs(x) + floor));
    }
  }
  return r;
}

const brdf::ResampleOptions kRule{.k = 6, .weights = brdf::Weights::wendland};

TEST(SpcSamples, AFineCodingDecodesToTheGridTheExactSamplesResampleTo) {
  const Samples s = gonio_samples("red-plastic", 3000, 1);
  const SpcSampleSet set = s.set();
  const auto bytes = encode_spc(set, self_basis(set, kGrid.size()), {.rule = kRule, .step = 1e-4});
  EXPECT_EQ(spc_format_version(bytes, "f.spc"), 4u);
  const store::Grid back = decode_spc(bytes, "f.spc");
  const store::Grid exact = resample_samples(set, kRule);
  const Agreement a = agreement(exact, back, 1e-3);
  EXPECT_GT(a.both, 500000u);
  EXPECT_EQ(a.only_a + a.only_b, 0u);  // the exact angles: the same support
  EXPECT_LT(a.worst, 2e-3);
}

// The coefficient form is sized unwritten and its cells without data are zeroed after the fill: they must read 0
// (under AddressSanitizer a fresh allocation's first 4 KB hold 0xbe bytes, so cell 0 would not).
TEST(SpcSamples, CellsWithoutDataHoldZeroCoefficients) {
  const Samples s = gonio_samples("red-plastic", 2000, 3);
  const SpcSampleSet set = s.set();
  const auto bytes = encode_spc(set, self_basis(set, 3), {.rule = kRule, .step = 0.05});
  const SpcCoefficients c = decode_spc_coefficients(bytes, "z.spc");
  const store::Grid grid = expand_spc(c);
  ASSERT_EQ(c.valid[0], 0);  // theta_h = theta_d = 0 lies farther than max_gap from every sample (theta_i >= 0.17)
  std::size_t without = 0;
  for (std::size_t cell = 0; cell < brdf::kMerlCells; ++cell) {
    ASSERT_EQ(c.valid[cell] == 1, grid.brdf[cell] >= 0) << cell;
    if (c.valid[cell]) continue;
    ++without;
    for (std::size_t j = 0; j < c.k(); ++j) ASSERT_EQ(c.values[cell * c.k() + j], 0.0f) << cell;
  }
  EXPECT_GT(without, 100000u);
}

TEST(SpcSamples, TheReportedErrorIsTheDecodedFilesAndTheBytesAreTheSameOnAnyThreadCount) {
  const Samples s = gonio_samples("red-plastic", 2000, 2);
  const SpcSampleSet set = s.set();
  const SpcBasis basis = self_basis(set, 3);
  const int threads = omp_get_max_threads();
  SpcReport rep;
  omp_set_num_threads(1);
  const auto one = encode_spc(set, basis, {.rule = kRule, .step = 0.05}, &rep);
  omp_set_num_threads(2);
  const auto two = encode_spc(set, basis, {.rule = kRule, .step = 0.05});
  omp_set_num_threads(threads);
  EXPECT_EQ(one, two);
  const store::Grid back = decode_spc(one, "r.spc"), exact = resample_samples(set, kRule);
  double sum2 = 0, count = 0;
  for (std::size_t c = 0; c < brdf::kMerlCells; ++c) {
    if (back.brdf[c] < 0 || exact.brdf[c] < 0) continue;
    for (std::size_t q = 0; q < kGrid.size(); ++q) {
      const double d = double(back.brdf[q * brdf::kMerlCells + c]) - double(exact.brdf[q * brdf::kMerlCells + c]);
      sum2 += d * d, ++count;
    }
  }
  EXPECT_NEAR(rep.rms_error, std::sqrt(sum2 / count), 1e-6 * rep.rms_error);
  EXPECT_EQ(rep.output_bytes, one.size());
  EXPECT_GT(rep.rms_error, 0);
}

TEST(SpcSamples, TheTargetIsMetAsAnIndependentSuiteRunMeasuresIt) {
  const Samples s = gonio_samples("cyan-gloss", 2500, 3);
  const SpcSampleSet set = s.set();
  const store::Grid exact = resample_samples(set, kRule);
  const LightingSuite suite(kGrid, {.size = 24});
  const SpcTarget target{.de00_mean = 0.5, .de00_p95 = 1.5, .condition_mean = 1.0, .max_trials = 6};
  SpcTargetReport tr;
  SpcKReport kr;
  const auto bytes = encode_spc_samples_choosing_k(
      set, exact, [&set](std::size_t k) { return self_basis(set, k); }, kGrid.size(), {.rule = kRule}, target, suite,
      tr, kr);
  const test::ReferenceVerdict v = test::reference_verdict(exact, decode_spc(bytes, "t.spc"), suite);
  EXPECT_TRUE(tr.reached);
  EXPECT_TRUE(test::meets_target(v, target));
  EXPECT_NEAR(v.mean, tr.de00_mean, 0.02);
  // The samples, not the grid: far smaller than a float32 copy of the 2500 spectra.
  EXPECT_LT(bytes.size(), 2500u * kGrid.size() * 4 / 4);
}

// A format-4 file with one header byte changed and its CRC recomputed: what a decoder must refuse on its own terms.
std::vector<std::uint8_t> with_byte(std::vector<std::uint8_t> b, std::size_t at, std::uint8_t v) {
  b[at] = v;
  const std::uint32_t crc = detail::crc32_of(std::span(b).first(b.size() - 4));
  std::memcpy(b.data() + b.size() - 4, &crc, 4);
  return b;
}

TEST(SpcSamples, BadFilesGiveOneInputErrorNamingTheFile) {
  const Samples s = gonio_samples("red-plastic", 300, 4);
  const SpcSampleSet set = s.set();
  const auto bytes = encode_spc(set, self_basis(set, 2), {.rule = kRule, .step = 0.05}, nullptr, "src");
  auto corrupt = bytes;
  corrupt[bytes.size() / 2] ^= 0x40;
  for (const auto& bad : {corrupt, std::vector<std::uint8_t>(bytes.begin(), bytes.end() - 9)}) {
    try {
      decode_spc(bad, "bad.spc");
      ADD_FAILURE() << "decoded a damaged file";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("bad.spc: ", 0), 0u) << e.what();
    }
  }
  // The mapping byte follows the header: magic, version, bands, k, two doubles, wavelengths, the float basis and
  // three strings ("1/sr", "src", "self").
  const std::size_t mapping_at = 8 + 4 + 8 + 16 + 8 * kGrid.size() + 4 * 2 * kGrid.size() + (4 + 4) + (4 + 3) + (4 + 4);
  EXPECT_NO_THROW(decode_spc(with_byte(bytes, mapping_at, 2), "ok.spc"));  // another valid mapping decodes
  EXPECT_THROW(decode_spc(with_byte(bytes, mapping_at, 7), "m.spc"), InputError);
  EXPECT_THROW(decode_spc(with_byte(bytes, mapping_at + 1, 9), "w.spc"), InputError);
}

TEST(SpcSamples, BadSamplesAndOptionsAreRefused) {
  Samples s = gonio_samples("red-plastic", 50, 5);
  const SpcBasis basis = self_basis(s.set(), 2);
  EXPECT_THROW(encode_spc(s.set(), basis, {.rule = kRule, .step = 0}), UsageError);
  EXPECT_THROW(encode_spc(s.set(), basis, {.rule = kRule, .shape_step_ratio = 0}), UsageError);
  EXPECT_THROW(encode_spc(s.set(), basis, {.rule = {.k = 0}}), UsageError);
  s.angles[5] = std::nan("");
  EXPECT_THROW(encode_spc(s.set(), basis, {.rule = kRule}), InputError);
  Samples empty;
  EXPECT_THROW(resample_samples(empty.set(), kRule), InputError);
}

}  // namespace
}  // namespace specula::codec
