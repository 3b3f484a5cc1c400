// .spc format 4, the samples method: scattered measurements coded with the rule that resamples them. Every sample's
// spectrum is split into a magnitude and a shape as the grid formats do; its angles are kept exactly, as indices into
// each column's distinct values (a goniometer repeats a few positions); the integer codes are range coded
// (codec/sample_coder.h). Decoding resamples the samples' coefficient vectors (a = m' c', one channel per basis
// spectrum, and a constant channel that marks the cells with support) onto the grid: resampling is linear in the
// values, so this is the resample of the decoded spectra on the basis, at exactly the measured configurations.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

#include "specula/codec/sample_coder.h"
#include "specula/codec/spc_detail.h"
#include "specula/core/parallel.h"

namespace specula::codec {
namespace detail {
namespace {

constexpr std::uint32_t kMaxSamples = std::uint32_t(1) << 24;
constexpr double kMaxAngle = 4 * 3.141592653589793;

void check_samples_options(const SpcSamplesOptions& o) {
  brdf::check_options(o.rule);
  if (!(std::isfinite(o.step) && o.step > 0 && o.step <= 10))
    throw UsageError("samples coding: step must be in (0, 10]");
  if (!(std::isfinite(o.shape_step_ratio) && o.shape_step_ratio > 0 && o.shape_step_ratio <= 100))
    throw UsageError("samples coding: shape_step_ratio must be in (0, 100]");
  if (!(std::isfinite(o.magnitude_scale) && o.magnitude_scale >= 0))
    throw UsageError("samples coding: magnitude_scale must be finite and >= 0");
}

// The shape of a sample set, checked: InputError for no samples, mismatched sizes or a non-finite value.
void check_samples(const SpcSampleSet& s) {
  const std::size_t bands = s.wavelengths.size();
  if (s.angles.size() % 4 != 0 || s.values.size() != s.size() * bands)
    throw InputError("samples: " + std::to_string(s.angles.size()) + " angles and " + std::to_string(s.values.size()) +
                     " values do not make samples of 4 angles and " + std::to_string(bands) + " bands");
  if (s.size() == 0) throw InputError("samples: there are none to code");
  if (s.size() > kMaxSamples)
    throw InputError("samples: " + std::to_string(s.size()) + " samples; format 4 holds at most 2^24");
  for (const double a : s.angles)
    if (!(std::abs(a) <= kMaxAngle))
      throw InputError("samples: angle " + std::to_string(a) + " rad is not finite or beyond +-4 pi");
  for (const float v : s.values)
    if (!std::isfinite(v)) throw InputError("samples: a value is not finite");
  if (!(std::isfinite(s.scale) && s.scale > 0)) throw InputError("samples: scale must be finite and positive");
}

// A tenth of the median positive magnitude (1 if there is none), as the grid formats choose s.
double median_scale(std::vector<float> mag) {
  std::erase_if(mag, [](float m) { return !(m > 0); });
  if (mag.empty()) return 1;
  std::nth_element(mag.begin(), mag.begin() + std::ptrdiff_t(mag.size() / 2), mag.end());
  return 0.1 * double(mag[mag.size() / 2]);
}

// Each angle column's distinct values, ascending, and every sample's index among them.
void palettes(std::span<const double> angles, std::array<std::vector<double>, 4>& palette,
              std::vector<std::uint32_t>& index) {
  const std::size_t n = angles.size() / 4;
  index.resize(4 * n);
  for (std::size_t a = 0; a < 4; ++a) {
    std::vector<double>& p = palette[a];
    p.resize(n);
    for (std::size_t i = 0; i < n; ++i) p[i] = angles[4 * i + a];
    std::sort(p.begin(), p.end());
    p.erase(std::unique(p.begin(), p.end()), p.end());
    for (std::size_t i = 0; i < n; ++i)
      index[4 * i + a] = std::uint32_t(std::lower_bound(p.begin(), p.end(), angles[4 * i + a]) - p.begin());
  }
}

// The integer codes of a sample set at one step, and everything decoding needs besides.
struct SampleCodes {
  std::size_t bands = 0;
  double s = 1, step_m = 1, step_c = 1;
  std::array<std::vector<double>, 4> palette;
  SampleCodeStreams streams;
};

// What decoding a coded sample set gives: the coefficient form on the grid under `rule`.
SpcCoefficients resample_codes(const SampleCodes& cd, const Eigen::MatrixXd& basis, const brdf::ResampleOptions& rule) {
  const SampleCodeStreams& st = cd.streams;
  const std::size_t n = st.n, k = st.k;
  std::vector<double> angles(4 * n);
  for (std::size_t i = 0; i < 4 * n; ++i) angles[i] = cd.palette[i % 4][st.index[i]];
  std::vector<float> values(k * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double m = cd.s * std::expm1(double(st.mag[i]) * cd.step_m);
    for (std::size_t j = 0; j < k; ++j) values[i * k + j] = float(m * (double(st.shape[i * k + j]) * cd.step_c));
  }
  SpcCoefficients c;
  c.basis = basis;
  // Sized unwritten: the fill writes the cells with data and the rest are zeroed after it, both on all threads, so
  // that the pages are first touched there rather than by one thread zeroing them all.
  c.values.resize(kMerlCells * k);
  c.valid.assign(kMerlCells, 0);
  brdf::Resampler(angles, values, k, rule).fill_cells(c.values, c.valid);
  constexpr std::size_t kBlock = 4096;
  parallel_for((kMerlCells + kBlock - 1) / kBlock, [&](std::size_t b) {
    for (std::size_t cell = b * kBlock; cell < std::min(kMerlCells, (b + 1) * kBlock); ++cell)
      if (!c.valid[cell]) std::fill_n(c.values.begin() + std::ptrdiff_t(cell * k), k, 0.0f);
  });
  return c;
}

}  // namespace

struct SamplesModel::Impl {
  const SpcSampleSet* samples = nullptr;
  const SpcBasis* basis = nullptr;
  const store::Grid* reference = nullptr;
  SpcSamplesOptions options;
  double s = 1;
  std::vector<double> y;  // log(1 + m / s) per sample
  std::vector<double> c;  // n x k shape coefficients
  std::array<std::vector<double>, 4> palette;
  std::vector<std::uint32_t> index;
  double max_y = 0, max_c = 0;
  Eigen::MatrixXd rows;  // the basis as the file stores it (float)

  SampleCodes codes(double step) const {
    SampleCodes cd{.bands = samples->wavelengths.size(),
                   .s = s,
                   .step_m = step,
                   .step_c = step * options.shape_step_ratio,
                   .palette = palette};
    SampleCodeStreams& st = cd.streams;
    st.n = samples->size();
    st.k = basis->k();
    for (std::size_t a = 0; a < 4; ++a) st.palette_size[a] = std::uint32_t(palette[a].size());
    st.index = index;
    st.mag.resize(st.n);
    st.shape.resize(st.n * st.k);
    for (std::size_t i = 0; i < st.n; ++i) st.mag[i] = std::llround(y[i] / cd.step_m);
    for (std::size_t i = 0; i < st.n * st.k; ++i) st.shape[i] = std::llround(c[i] / cd.step_c);
    st.delta.resize(st.k + 1);
    st.delta[0] = prefer_differences(st.mag, 1, 0, st.n);
    for (std::size_t j = 0; j < st.k; ++j) st.delta[j + 1] = prefer_differences(st.shape, st.k, j, st.n);
    return cd;
  }
};

SamplesModel::SamplesModel(const SpcSampleSet& samples, const SpcBasis& basis, const SpcSamplesOptions& o,
                           const store::Grid& reference)
    : impl_(std::make_unique<Impl>()) {
  check_samples_options(o);
  check_samples(samples);
  const std::size_t bands = samples.wavelengths.size(), n = samples.size(), k = basis.k();
  if (std::size_t(basis.rows.cols()) != bands || !basis.wavelengths.approx_equal(samples.wavelengths))
    throw InputError("the samples have " + samples.wavelengths.describe() + ", basis " + basis.reference + " has " +
                     basis.wavelengths.describe() + "; code samples with a basis on their own wavelengths");
  Impl& m = *impl_;
  m.samples = &samples;
  m.basis = &basis;
  m.reference = &reference;
  m.options = o;
  m.rows = basis.rows.cast<float>().cast<double>();
  std::vector<float> mag(n);
  for (std::size_t i = 0; i < n; ++i) {
    double sum = 0;
    for (std::size_t b = 0; b < bands; ++b) sum += samples.values[i * bands + b];
    mag[i] = float(std::max(0.0, sum / double(bands)));  // a sample of negative mean is coded as 0
  }
  m.s = o.magnitude_scale > 0 ? o.magnitude_scale : median_scale(mag);
  m.y.resize(n);
  m.c.assign(n * k, 0.0);
  Eigen::VectorXd r(static_cast<Eigen::Index>(bands));
  for (std::size_t i = 0; i < n; ++i) {
    m.y[i] = std::log1p(double(mag[i]) / m.s);
    m.max_y = std::max(m.max_y, m.y[i]);
    if (!(mag[i] > 0)) continue;
    for (std::size_t b = 0; b < bands; ++b) r[Eigen::Index(b)] = double(samples.values[i * bands + b]) / double(mag[i]);
    const Eigen::VectorXd ci = basis.rows * r;
    for (std::size_t j = 0; j < k; ++j) {
      m.c[i * k + j] = ci[Eigen::Index(j)];
      m.max_c = std::max(m.max_c, std::abs(ci[Eigen::Index(j)]));
    }
  }
  palettes(samples.angles, m.palette, m.index);
}

SamplesModel::~SamplesModel() = default;

double SamplesModel::finest_step() const {
  const Impl& m = *impl_;
  return std::max({1e-6, m.max_y / double(kMaxSampleCode - 1),
                   m.max_c / (m.options.shape_step_ratio * double(kMaxSampleCode - 1))});
}

void SamplesModel::decoded(double step, store::Grid& out) const {
  const Impl& m = *impl_;
  SpcCoefficients c = resample_codes(m.codes(step), m.rows, m.options.rule);
  c.wavelengths = m.samples->wavelengths;
  c.scale = m.samples->scale;
  c.units = m.samples->units;
  expand_spc(c, out);
}

namespace {

// The container of docs/codec-format.md (format 4) around a coding.
std::vector<std::uint8_t> pack(const SampleCodes& cd, const SpcSampleSet& samples, const SpcBasis& basis,
                               const brdf::ResampleOptions& rule, const std::string& source) {
  const SampleCodeStreams& st = cd.streams;
  std::vector<std::uint8_t> out;
  put_head(out, 4, cd.bands, st.k, samples.scale, cd.s);
  for (const double w : samples.wavelengths.values()) put(out, w);
  put_basis_and_labels(out, basis, st.k, cd.bands, samples.units, source);
  put(out, std::uint8_t(rule.mapping));
  put(out, std::uint8_t(rule.weights));
  put(out, std::uint32_t(rule.k));
  put(out, rule.power);
  put(out, rule.max_gap);
  put(out, std::uint32_t(st.n));
  put(out, cd.step_m);
  put(out, cd.step_c);
  for (const auto& p : cd.palette) {
    put(out, std::uint32_t(p.size()));
    for (const double v : p) put(out, v);
  }
  put_bytes(out, st.delta.data(), st.delta.size());
  const std::vector<std::uint8_t> coded = encode_sample_codes(st);
  put(out, std::uint32_t(coded.size()));
  put_bytes(out, coded.data(), coded.size());
  put(out, crc32_of(out));
  return out;
}

// RMS and largest difference of g from ref over the cells valid in both (1/sr).
void measure(const store::Grid& g, const store::Grid& ref, SpcReport& report) {
  const std::size_t bands = ref.bands();
  double sum2 = 0;
  std::uint64_t count = 0;
  for (std::size_t cell = 0; cell < kMerlCells; ++cell) {
    if (g.brdf[cell] < 0 || ref.brdf[cell] < 0) continue;
    ++report.valid_cells;
    for (std::size_t b = 0; b < bands; ++b) {
      const double d = (double(g.brdf[b * kMerlCells + cell]) - double(ref.brdf[b * kMerlCells + cell])) * ref.scale;
      report.max_abs_error = std::max(report.max_abs_error, std::abs(d));
      sum2 += d * d;
      ++count;
    }
  }
  report.rms_error = count ? std::sqrt(sum2 / double(count)) : 0.0;
}

// The resampling rule of a format-4 header, checked.
brdf::ResampleOptions read_rule(Reader& r, const std::string& label) {
  brdf::ResampleOptions rule;
  const auto mapping = r.get<std::uint8_t>("mapping"), weights = r.get<std::uint8_t>("weights");
  if (mapping > std::uint8_t(brdf::Mapping::halfdiff) || weights > std::uint8_t(brdf::Weights::loess))
    throw InputError(label + ": .spc resampling rule names mapping " + std::to_string(mapping) + " and weights " +
                     std::to_string(weights) + "; this specula knows mappings 0-2 and weights 0-4");
  rule.mapping = brdf::Mapping(mapping);
  rule.weights = brdf::Weights(weights);
  rule.k = r.get<std::uint32_t>("neighbours");
  rule.power = r.get<double>("power");
  rule.max_gap = r.get<double>("max gap");
  try {
    brdf::check_options(rule);
  } catch (const UsageError& e) {
    throw InputError(label + ": .spc resampling rule is invalid: " + e.what());
  }
  return rule;
}

// The four angle palettes of a format-4 file, each 1 to n values, finite, within +-4 pi and strictly ascending.
void read_palettes(Reader& r, std::size_t n, SampleCodes& cd, const std::string& label) {
  for (std::size_t a = 0; a < 4; ++a) {
    const auto count = r.get<std::uint32_t>("palette size");
    if (count < 1 || count > n)
      throw InputError(label + ": .spc angle column " + std::to_string(a) + " has " + std::to_string(count) +
                       " distinct values for " + std::to_string(n) + " samples");
    std::vector<double>& p = cd.palette[a];
    p.resize(count);
    std::memcpy(p.data(), r.take(8 * std::size_t(count), "palette"), 8 * std::size_t(count));
    for (std::size_t i = 0; i < count; ++i)
      if (!(std::abs(p[i]) <= kMaxAngle) || (i > 0 && !(p[i] > p[i - 1])))
        throw InputError(label + ": .spc angle column " + std::to_string(a) +
                         " is not an ascending list of angles within +-4 pi");
    cd.streams.palette_size[a] = count;
  }
}

}  // namespace

std::vector<std::uint8_t> SamplesModel::code(double step, SpcReport* report, const std::string& source) const {
  const Impl& m = *impl_;
  const SampleCodes cd = m.codes(step);
  std::vector<std::uint8_t> out = pack(cd, *m.samples, *m.basis, m.options.rule, source);
  if (report) {
    *report = {};
    report->input_bytes = std::uint64_t(cd.bands) * kMerlCells * 8;
    report->output_bytes = out.size();
    report->magnitude_scale = cd.s * m.samples->scale;
    report->magnitude_step = cd.step_m;
    report->shape_step = cd.step_c;
    store::Grid g;
    decoded(step, g);
    measure(g, *m.reference, *report);
  }
  return out;
}

SpcCoefficients decode_samples(std::span<const std::uint8_t> bytes, const std::string& label, bool header_only) {
  Reader r(bytes.first(bytes.size() - 4), label);
  r.take(sizeof kSpcMagic + 4, "magic and version");
  const auto [bands, k] = read_shape(r, label);
  SpcCoefficients c;
  const auto [scale, magnitude_scale] = read_scales(r, label);
  c.scale = scale;
  SampleCodes cd{.bands = bands, .s = magnitude_scale};
  std::vector<double> wl(bands);
  std::memcpy(wl.data(), r.take(8 * std::size_t(bands), "wavelengths"), 8 * std::size_t(bands));
  c.wavelengths = checked_wavelengths(std::move(wl), label);
  c.basis = read_basis<float>(r, k, bands, label);
  c.units = r.string("units");
  c.source = r.string("source");
  c.reference = r.string("basis reference");
  if (header_only) return c;
  const brdf::ResampleOptions rule = read_rule(r, label);
  SampleCodeStreams& st = cd.streams;
  st.n = r.get<std::uint32_t>("samples");
  st.k = k;
  if (st.n == 0 || st.n > kMaxSamples)
    throw InputError(label + ": .spc holds " + std::to_string(st.n) + " samples; 1 to 2^24 are valid");
  cd.step_m = r.get<double>("magnitude step");
  cd.step_c = r.get<double>("shape step");
  for (const auto& [v, what] : {std::pair{cd.step_m, "magnitude step"}, std::pair{cd.step_c, "shape step"}})
    if (!(std::isfinite(v) && v > 0 && v <= 1e3))
      throw InputError(label + ": .spc field '" + what + "' is " + std::to_string(v) + "; it must be in (0, 1000]");
  read_palettes(r, st.n, cd, label);
  const std::uint8_t* delta = r.take(k + 1, "difference flags");
  st.delta.assign(delta, delta + k + 1);
  for (const auto f : st.delta)
    if (f > 1) throw InputError(label + ": .spc difference flag " + std::to_string(f) + " is neither 0 nor 1");
  const auto size = r.get<std::uint32_t>("stream length");
  if (!decode_sample_codes({r.take(size, "stream"), size}, st))
    throw InputError(label + ": .spc sample stream is truncated or corrupt");
  for (const auto q : st.mag)
    if (double(q) * cd.step_m > 700) throw InputError(label + ": .spc holds a magnitude beyond a double's range");
  if (r.at() != bytes.size() - 4) throw InputError(label + ": .spc has bytes after its sample stream");
  SpcCoefficients out = resample_codes(cd, c.basis, rule);
  out.wavelengths = std::move(c.wavelengths);
  out.scale = c.scale;
  out.units = std::move(c.units);
  out.source = std::move(c.source);
  out.reference = std::move(c.reference);
  return out;
}

}  // namespace detail

store::Grid resample_samples(const SpcSampleSet& samples, const brdf::ResampleOptions& rule) {
  detail::check_samples(samples);
  brdf::check_options(rule);
  store::Grid g;
  g.wavelengths = samples.wavelengths;
  g.scale = samples.scale;
  g.units = samples.units;
  g.brdf.assign(samples.wavelengths.size() * detail::kMerlCells, -1.0f);
  brdf::Resampler(samples.angles, samples.values, samples.wavelengths.size(), rule).fill_grid(g.brdf);
  return g;
}

std::vector<std::uint8_t> encode_spc(const SpcSampleSet& samples, const SpcBasis& basis, const SpcSamplesOptions& o,
                                     SpcReport* report, const std::string& source) {
  detail::check_samples_options(o);
  const store::Grid reference = resample_samples(samples, o.rule);
  const detail::SamplesModel model(samples, basis, o, reference);
  return model.code(o.step, report, source);
}

}  // namespace specula::codec
