// Tests of the synthetic natural-scene database (store/synth.h).
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "specula/core/cie.h"
#include "specula/core/error.h"
#include "specula/store/synth.h"
#include "test_support.h"

namespace specula::store {
namespace {

SynthOptions small_options(std::size_t h = 64, std::size_t w = 64) {
  SynthOptions o;
  o.images = 16;
  o.height = h;
  o.width = w;
  o.seed = 7;
  return o;
}

bool bitwise_equal(const Cube& a, const Cube& b) {
  return a.height == b.height && a.width == b.width && a.bands == b.bands && a.mask == b.mask &&
         a.data.size() == b.data.size() &&
         std::memcmp(a.data.data(), b.data.data(), a.data.size() * sizeof(float)) == 0;
}

TEST(Synth, ShapeUnitsAndProvenance) {
  const SynthOptions o = small_options(40, 56);
  const Cube c = synthesize_image(o, 3);
  EXPECT_EQ(c.height, 40u);
  EXPECT_EQ(c.width, 56u);
  EXPECT_EQ(c.bands, 31u);
  EXPECT_EQ(c.data.size(), 40u * 56u * 31u);
  EXPECT_TRUE(c.wavelengths.approx_equal(o.wavelengths));
  EXPECT_EQ(c.units, "radiance");
  EXPECT_EQ(c.provenance.importer, "synth-db");
  EXPECT_TRUE(c.mask.empty() || c.mask.size() == 40u * 56u);
}

TEST(Synth, DeterministicPerSeedAndIndex) {
  const SynthOptions o = small_options(48, 80);
  const Cube a = synthesize_image(o, 2), b = synthesize_image(o, 2);
  EXPECT_TRUE(bitwise_equal(a, b));
  const Cube c = synthesize_image(o, 3);
  EXPECT_FALSE(bitwise_equal(a, c));
  SynthOptions other = o;
  other.seed = 8;
  EXPECT_FALSE(bitwise_equal(a, synthesize_image(other, 2)));
  // the number of images in the database does not change image 2
  SynthOptions more = o;
  more.images = 1000;
  EXPECT_TRUE(bitwise_equal(a, synthesize_image(more, 2)));
}

TEST(Synth, SameResultOnAnyThreadCount) {
  const SynthOptions o = small_options(150, 130);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const Cube one = synthesize_image(o, 5);
  omp_set_num_threads(2);
  const Cube two = synthesize_image(o, 5);
  omp_set_num_threads(3);
  const Cube three = synthesize_image(o, 5);
  omp_set_num_threads(saved);
  EXPECT_TRUE(bitwise_equal(one, two));
  EXPECT_TRUE(bitwise_equal(one, three));
  // above 16 MB the cube's pages are pre-faulted by a thread team first; 2 bands exercise the row-end path
  SynthOptions big = small_options(400, 360);
  SynthOptions narrow = small_options(37, 53);
  narrow.wavelengths = WavelengthGrid::range(500, 600, 100);
  omp_set_num_threads(1);
  const Cube big1 = synthesize_image(big, 1), narrow1 = synthesize_image(narrow, 1);
  omp_set_num_threads(2);
  const Cube big2 = synthesize_image(big, 1), narrow2 = synthesize_image(narrow, 1);
  omp_set_num_threads(saved);
  EXPECT_TRUE(bitwise_equal(big1, big2));
  EXPECT_TRUE(bitwise_equal(narrow1, narrow2));
}

TEST(Synth, MaskedRectanglesInSomeImages) {
  const SynthOptions o = small_options(64, 64);
  int with_mask = 0, without = 0;
  for (std::size_t i = 0; i < o.images; ++i) {
    const Cube c = synthesize_image(o, i);
    std::size_t invalid = 0;
    for (std::size_t y = 0; y < c.height; ++y)
      for (std::size_t x = 0; x < c.width; ++x) invalid += !c.valid(y, x);
    if (invalid > 0)
      ++with_mask;
    else
      ++without;
    EXPECT_LT(invalid, c.height * c.width / 2) << "image " << i << " is mostly masked";
  }
  EXPECT_GT(with_mask, 0);
  EXPECT_GT(without, 0);
}

TEST(Synth, FiniteAndMostlyPositiveValues) {
  const SynthOptions o = small_options(64, 64);
  for (std::size_t i = 0; i < 6; ++i) {
    const Cube c = synthesize_image(o, i);
    std::size_t negative = 0;
    double sum = 0;
    for (float v : c.data) {
      ASSERT_TRUE(std::isfinite(v)) << "image " << i;
      negative += v < 0;
      sum += v;
    }
    EXPECT_GT(sum / double(c.data.size()), 0.0);
    EXPECT_LT(negative, c.data.size() / 100) << "image " << i;
  }
  // noise-free radiance is never negative
  SynthOptions clean = o;
  clean.noise = 0;
  for (std::size_t i = 0; i < 4; ++i)
    for (float v : synthesize_image(clean, i).data) ASSERT_GE(v, 0.0f);
}

// Mean absolute second difference across bands relative to the mean absolute value, over all pixels.
// White noise scores above 1; radiance under CIE daylight about 0.05 (the daylight's own ripples).
double roughness(const Cube& c) {
  double second = 0, level = 0;
  for (std::size_t p = 0; p < c.height * c.width; ++p) {
    const float* s = c.data.data() + p * c.bands;
    for (std::size_t b = 1; b + 1 < c.bands; ++b) second += std::abs(s[b - 1] - 2 * s[b] + s[b + 1]);
    for (std::size_t b = 0; b < c.bands; ++b) level += std::abs(s[b]);
  }
  return (second / double(c.bands - 2)) / (level / double(c.bands));
}

TEST(Synth, SpectraAreSmooth) {
  SynthOptions o = small_options(64, 64);
  SynthOptions clean = o;
  clean.noise = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_LT(roughness(synthesize_image(clean, i)), 0.1) << "image " << i;
    EXPECT_LT(roughness(synthesize_image(o, i)), 0.15) << "image " << i;
  }
}

// PCA as in Braley §7.3: covariance of the valid pixels, eigenvalues sorted descending.
Eigen::VectorXd pca_eigenvalues(const SynthOptions& o, std::size_t first, std::size_t count) {
  const std::size_t B = o.wavelengths.size();
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(Eigen::Index(B));
  Eigen::MatrixXd outer = Eigen::MatrixXd::Zero(Eigen::Index(B), Eigen::Index(B));
  double n = 0;
  for (std::size_t i = first; i < first + count; ++i) {
    const Cube c = synthesize_image(o, i);
    for (std::size_t y = 0; y < c.height; ++y)
      for (std::size_t x = 0; x < c.width; ++x) {
        if (!c.valid(y, x)) continue;
        const Eigen::VectorXd s = Eigen::Map<const Eigen::VectorXf>(c.pixel(y, x), Eigen::Index(B)).cast<double>();
        sum += s;
        outer.noalias() += s * s.transpose();
        n += 1;
      }
  }
  const Eigen::VectorXd mean = sum / n;
  const Eigen::MatrixXd cov = outer / n - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(cov);
  return es.eigenvalues().reverse();
}

TEST(Synth, PcaLooksLikeNaturalData) {
  const SynthOptions o = small_options(64, 64);
  const Eigen::VectorXd ev = pca_eigenvalues(o, 0, 6);
  const double total = ev.sum();
  ASSERT_GT(total, 0);
  const double first3 = ev.head(3).sum() / total, first6 = ev.head(6).sum() / total;
  EXPECT_GE(first3, 0.95) << "eigenvalues " << ev.transpose();
  EXPECT_GE(first6, 0.99) << "eigenvalues " << ev.transpose();
  EXPECT_LT(first3, 0.99999) << "suspiciously low-dimensional";
  // falls off fast at first, then a long tail of noise: every eigenvalue positive, each one no larger than
  // the one before, the leading ones well separated
  for (Eigen::Index k = 0; k < ev.size(); ++k) EXPECT_GT(ev[k], 0) << "component " << k;
  for (Eigen::Index k = 1; k < ev.size(); ++k) EXPECT_LE(ev[k], ev[k - 1]) << "component " << k;
  EXPECT_GT(ev[0], 3 * ev[1]);
  EXPECT_GT(ev[1], 2 * ev[3]);
  EXPECT_GT(ev[3], 2 * ev[10]);
  EXPECT_LT(ev[10] / total, 1e-3);
  // the noise floor: the last third of the spectrum of eigenvalues is flat within a factor of 10
  EXPECT_LT(ev[20], 10 * ev[30]);
}

TEST(Synth, NoiseFreeRegionHasOneSpectralShape) {
  // With noise = 0 a pixel is a scalar (shading x texture) times reflectance x illuminant, so two pixels of
  // the same region under the same light have a band-independent ratio. Neighbouring pixels mostly share
  // region and light; boundaries and penumbrae are the exceptions.
  SynthOptions o = small_options(64, 64);
  o.noise = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    const Cube c = synthesize_image(o, i);
    std::size_t pairs = 0, constant = 0;
    for (std::size_t y = 0; y < c.height; ++y)
      for (std::size_t x = 0; x + 1 < c.width; ++x) {
        const float* p = c.pixel(y, x);
        const float* q = c.pixel(y, x + 1);
        double lo = INFINITY, hi = -INFINITY;
        for (std::size_t b = 0; b < c.bands; ++b) {
          ASSERT_GT(q[b], 0.0f);
          const double r = double(p[b]) / double(q[b]);
          lo = std::min(lo, r);
          hi = std::max(hi, r);
        }
        ++pairs;
        constant += (hi - lo) <= 1e-5 * hi;
      }
    EXPECT_GT(double(constant) / double(pairs), 0.75) << "image " << i;
  }
}

TEST(Synth, RadianceIsSmoothReflectanceTimesDaylight) {
  // A noise-free pixel is a smooth reflectance times CIE daylight (sun plus sky), so dividing it by the
  // best-fitting CIE daylight removes the daylight's ripples (Fraunhofer and absorption features, visible at
  // 5 nm sampling) and leaves a much smoother curve.
  SynthOptions o = small_options(64, 64);
  o.noise = 0;
  o.wavelengths = WavelengthGrid::range(400, 720, 5);
  std::vector<Eigen::VectorXd> daylights;
  for (double cct = 4000; cct <= 25000; cct += 250) daylights.push_back(specula::daylight(cct, o.wavelengths));
  for (std::size_t i = 0; i < 4; ++i) {
    const Cube c = synthesize_image(o, i);
    auto rough = [&](auto f) {
      double s2 = 0, s0 = 0;
      for (std::size_t b = 1; b + 1 < c.bands; ++b) s2 += std::abs(f(b - 1) - 2 * f(b) + f(b + 1));
      for (std::size_t b = 0; b < c.bands; ++b) s0 += std::abs(f(b));
      return s2 / s0;
    };
    double raw = 0, divided = 0;
    const std::size_t n = c.height * c.width;
    for (std::size_t k = 0; k < 100; ++k) {
      const float* p = c.data.data() + ((k * 7919) % n) * c.bands;
      raw += rough([&](std::size_t b) { return double(p[b]); });
      double best = INFINITY;
      for (const auto& d : daylights)
        best = std::min(best, rough([&](std::size_t b) { return double(p[b]) / d[Eigen::Index(b)]; }));
      divided += best;
    }
    EXPECT_LT(divided, 0.7 * raw) << "image " << i;
  }
}

TEST(Synth, RejectsBadOptions) {
  SynthOptions o = small_options();
  o.height = 0;
  EXPECT_THROW(synthesize_image(o, 0), UsageError);
  o = small_options();
  o.width = 0;
  EXPECT_THROW(synthesize_image(o, 0), UsageError);
  o = small_options();
  o.wavelengths = WavelengthGrid();
  EXPECT_THROW(synthesize_image(o, 0), UsageError);
  o = small_options();
  EXPECT_THROW(synthesize_image(o, o.images), UsageError);
  o.images = 0;
  EXPECT_THROW(synthesize_image(o, 0), UsageError);
  o = small_options();
  o.noise = -0.1;
  EXPECT_THROW(synthesize_image(o, 0), UsageError);
  o = small_options();
  o.wavelengths = WavelengthGrid::range(200, 400, 10);  // outside the daylight table
  EXPECT_THROW(synthesize_image(o, 0), UsageError);
}

TEST(Synth, OtherGridsAndTinyImages) {
  SynthOptions o = small_options(1, 1);
  o.wavelengths = WavelengthGrid::range(400, 700, 100);
  const Cube c = synthesize_image(o, 0);
  ASSERT_EQ(c.data.size(), 4u);
  for (float v : c.data) EXPECT_TRUE(std::isfinite(v));
  o = small_options(9, 17);
  o.wavelengths = WavelengthGrid::range(380, 780, 4);  // 101 bands, above the small-buffer size
  const Cube d = synthesize_image(o, 1);
  ASSERT_EQ(d.bands, 101u);
  for (float v : d.data) EXPECT_TRUE(std::isfinite(v));
}

}  // namespace
}  // namespace specula::store
