// .spc format 4, the samples method: scattered measurements coded with the rule that resamples them. Every sample's
// spectrum is split into a magnitude and a shape as the grid formats do, its angles quantised to a fixed step, the
// integer codes written as zigzag varints (angles as differences from the previous sample) in three zstd streams.
// Decoding resamples the samples' coefficient vectors (a = m' c', one channel per basis spectrum, and a constant
// channel that marks the cells with support) onto the grid: resampling is linear in the values, so this is the
// resample of the decoded spectra on the basis.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "specula/codec/spc_detail.h"
#include "specula/core/parallel.h"

namespace specula::codec {
namespace detail {
namespace {

constexpr std::int64_t kMaxSampleCode = std::int64_t(1) << 27;
constexpr std::uint32_t kMaxSamples = std::uint32_t(1) << 24;
constexpr int kZstdLevel = 19;
constexpr double kMaxAngle = 4 * 3.141592653589793;

void check_samples_options(const SpcSamplesOptions& o) {
  brdf::check_options(o.rule);
  if (!(std::isfinite(o.step) && o.step > 0 && o.step <= 10))
    throw UsageError("samples coding: step must be in (0, 10]");
  if (!(std::isfinite(o.shape_step_ratio) && o.shape_step_ratio > 0 && o.shape_step_ratio <= 100))
    throw UsageError("samples coding: shape_step_ratio must be in (0, 100]");
  if (!(std::isfinite(o.angle_step) && o.angle_step >= 1e-7 && o.angle_step <= 0.01))
    throw UsageError("samples coding: angle_step must be in [1e-7, 0.01] radians");
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

std::uint64_t zigzag(std::int64_t v) { return (std::uint64_t(v) << 1) ^ std::uint64_t(v >> 63); }
std::int64_t unzigzag(std::uint64_t u) { return std::int64_t(u >> 1) ^ -std::int64_t(u & 1); }

void put_varint(std::vector<std::uint8_t>& out, std::int64_t v) {
  std::uint64_t u = zigzag(v);
  while (u >= 0x80) {
    out.push_back(std::uint8_t(u | 0x80));
    u >>= 7;
  }
  out.push_back(std::uint8_t(u));
}

// `count` varints of `in` from byte `at` on (advanced past them).
std::vector<std::int64_t> get_varints_at(const std::vector<std::uint8_t>& in, std::size_t count, std::size_t& at,
                                         const std::string& label, const char* what) {
  std::vector<std::int64_t> out(count);
  for (std::size_t i = 0; i < count; ++i) {
    std::uint64_t u = 0;
    for (int shift = 0;; shift += 7) {
      if (at >= in.size() || shift > 35)
        throw InputError(label + ": .spc " + what + " stream ends or overflows at code " + std::to_string(i));
      const std::uint8_t b = in[at++];
      u |= std::uint64_t(b & 0x7f) << shift;
      if (!(b & 0x80)) break;
    }
    out[i] = unzigzag(u);
  }
  return out;
}

// Reads `count` varints of a decompressed stream; InputError naming the stream when they are not exactly that.
std::vector<std::int64_t> get_varints(const std::vector<std::uint8_t>& in, std::size_t count, const std::string& label,
                                      const char* what) {
  std::size_t at = 0;
  std::vector<std::int64_t> out = get_varints_at(in, count, at, label, what);
  if (at != in.size()) throw InputError(label + ": .spc " + what + " stream has bytes after its codes");
  return out;
}

// The n x 4 angle codes of a stream of put_angle_column's columns.
std::vector<std::int64_t> get_angle_columns(const std::vector<std::uint8_t>& in, std::size_t n,
                                            const std::string& label) {
  std::vector<std::int64_t> codes(4 * n);
  std::size_t at = 0;
  for (std::size_t a = 0; a < 4; ++a) {
    const std::int64_t count = get_varints_at(in, 1, at, label, "angles")[0];
    if (count < 1 || std::size_t(count) > n)
      throw InputError(label + ": .spc angle column " + std::to_string(a) + " claims " + std::to_string(count) +
                       " distinct values for " + std::to_string(n) + " samples");
    std::vector<std::int64_t> distinct = get_varints_at(in, std::size_t(count), at, label, "angles");
    for (std::size_t d = 1; d < distinct.size(); ++d) {
      if (distinct[d] <= 0) throw InputError(label + ": .spc angle column's values are not ascending");
      distinct[d] += distinct[d - 1];
      if (std::abs(distinct[d]) >= kMaxSampleCode) throw InputError(label + ": .spc holds a code beyond +-2^27");
    }
    const std::vector<std::int64_t> index = get_varints_at(in, n, at, label, "angles");
    for (std::size_t i = 0; i < n; ++i) {
      if (index[i] < 0 || index[i] >= count)
        throw InputError(label + ": .spc angle index " + std::to_string(index[i]) + " is not below " +
                         std::to_string(count));
      codes[4 * i + a] = distinct[std::size_t(index[i])];
    }
  }
  if (at != in.size()) throw InputError(label + ": .spc angles stream has bytes after its codes");
  return codes;
}

// One column of the n x 4 angle codes: its distinct codes ascending (the first, then differences) and each sample's
// index among them. Measured samples repeat a few positions of a goniometer, so the indices are small and zstd
// finds their patterns.
void put_angle_column(std::vector<std::uint8_t>& out, const std::vector<std::int64_t>& codes, std::size_t column) {
  std::vector<std::int64_t> col(codes.size() / 4);
  for (std::size_t i = 0; i < col.size(); ++i) col[i] = codes[4 * i + column];
  std::vector<std::int64_t> distinct = col;
  std::sort(distinct.begin(), distinct.end());
  distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  put_varint(out, std::int64_t(distinct.size()));
  for (std::size_t d = 0; d < distinct.size(); ++d) put_varint(out, distinct[d] - (d ? distinct[d - 1] : 0));
  for (const auto v : col) put_varint(out, std::lower_bound(distinct.begin(), distinct.end(), v) - distinct.begin());
}

// The integer codes of a sample set at one step, and everything decoding needs besides.
struct SampleCodes {
  std::size_t n = 0, k = 0, bands = 0;
  double s = 1, step_m = 1, step_c = 1, angle_step = 1e-4;
  std::vector<std::int64_t> angles;  // n x 4
  std::vector<std::int64_t> mag;     // n
  std::vector<std::int64_t> shape;   // n x k
};

// What decoding a coded sample set gives: the coefficient form on the grid under `rule`.
SpcCoefficients resample_codes(const SampleCodes& cd, const Eigen::MatrixXd& basis, const brdf::ResampleOptions& rule) {
  const std::size_t n = cd.n, k = cd.k, ch = k + 1;
  std::vector<double> angles(4 * n);
  for (std::size_t i = 0; i < 4 * n; ++i) angles[i] = double(cd.angles[i]) * cd.angle_step;
  std::vector<float> values(ch * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double m = cd.s * std::expm1(double(cd.mag[i]) * cd.step_m);
    for (std::size_t j = 0; j < k; ++j) values[i * ch + j] = float(m * (double(cd.shape[i * k + j]) * cd.step_c));
    values[i * ch + k] = 1.0f;  // resamples to 1 where a cell has support, -1 where it has none
  }
  std::vector<float> grid(ch * kMerlCells);
  brdf::Resampler(angles, values, ch, rule).fill_grid(grid);
  SpcCoefficients c;
  c.basis = basis;
  c.values.assign(kMerlCells * k, 0.0f);
  c.valid.assign(kMerlCells, 0);
  parallel_for(
      kMerlCells,
      [&](std::size_t cell) {
        if (!(grid[k * kMerlCells + cell] > 0)) return;
        c.valid[cell] = 1;
        for (std::size_t j = 0; j < k; ++j) c.values[cell * k + j] = grid[j * kMerlCells + cell];
      },
      kSlab);
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
  std::vector<std::int64_t> angles;
  double max_y = 0, max_c = 0;
  Eigen::MatrixXd rows;  // the basis as the file stores it (float)

  SampleCodes codes(double step) const {
    SampleCodes cd{
        .n = samples->size(), .k = basis->k(), .bands = basis->rows.cols() > 0 ? std::size_t(basis->rows.cols()) : 0};
    cd.s = s;
    cd.step_m = step;
    cd.step_c = step * options.shape_step_ratio;
    cd.angle_step = options.angle_step;
    cd.angles = angles;
    cd.mag.resize(cd.n);
    cd.shape.resize(cd.n * cd.k);
    for (std::size_t i = 0; i < cd.n; ++i) cd.mag[i] = std::llround(y[i] / cd.step_m);
    for (std::size_t i = 0; i < cd.n * cd.k; ++i) cd.shape[i] = std::llround(c[i] / cd.step_c);
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
  m.angles.resize(4 * n);
  for (std::size_t i = 0; i < 4 * n; ++i) {
    m.angles[i] = std::llround(samples.angles[i] / o.angle_step);
  }
}

SamplesModel::~SamplesModel() = default;

double SamplesModel::finest_step() const {
  const Impl& m = *impl_;
  return std::max({1e-6, m.max_y / double(kMaxSampleCode - 1),
                   m.max_c / (m.options.shape_step_ratio * double(kMaxSampleCode - 1))});
}

store::Grid SamplesModel::decoded(double step) const {
  const Impl& m = *impl_;
  SpcCoefficients c = resample_codes(m.codes(step), m.rows, m.options.rule);
  c.wavelengths = m.samples->wavelengths;
  c.scale = m.samples->scale;
  c.units = m.samples->units;
  return expand_spc(c);
}

std::vector<std::uint8_t> SamplesModel::code(double step, SpcReport* report, const std::string& source) const {
  const Impl& m = *impl_;
  const SampleCodes cd = m.codes(step);
  std::vector<std::uint8_t> angles, mags, shapes;
  for (std::size_t a = 0; a < 4; ++a) put_angle_column(angles, cd.angles, a);
  for (const auto v : cd.mag) put_varint(mags, v);
  for (std::size_t j = 0; j < cd.k; ++j)
    for (std::size_t i = 0; i < cd.n; ++i) put_varint(shapes, cd.shape[i * cd.k + j]);
  std::vector<std::uint8_t> out;
  put_bytes(out, kSpcMagic, sizeof kSpcMagic);
  put(out, std::uint32_t(4));
  put(out, std::uint32_t(cd.bands));
  put(out, std::uint32_t(cd.k));
  put(out, m.samples->scale);
  put(out, cd.s);
  for (const double w : m.samples->wavelengths.values()) put(out, w);
  for (std::size_t j = 0; j < cd.k; ++j)
    for (std::size_t b = 0; b < cd.bands; ++b) put(out, float(m.basis->rows(Eigen::Index(j), Eigen::Index(b))));
  put_string(out, m.samples->units);
  put_string(out, source);
  put_string(out, m.basis->reference);
  const brdf::ResampleOptions& rule = m.options.rule;
  put(out, std::uint8_t(rule.mapping));
  put(out, std::uint8_t(rule.weights));
  put(out, std::uint32_t(rule.k));
  put(out, rule.power);
  put(out, rule.max_gap);
  put(out, std::uint32_t(cd.n));
  put(out, cd.angle_step);
  put(out, cd.step_m);
  put(out, cd.step_c);
  for (const auto* raw : {&angles, &mags, &shapes}) {
    const auto z = zstd_compress(*raw, kZstdLevel);
    put(out, std::uint32_t(raw->size()));
    put(out, std::uint32_t(z.size()));
    put_bytes(out, z.data(), z.size());
  }
  put(out, crc32_of(out));
  if (report) {
    const store::Grid g = decoded(step);
    const store::Grid& ref = *m.reference;
    *report = {};
    report->input_bytes = std::uint64_t(cd.bands) * kMerlCells * 8;
    report->output_bytes = out.size();
    report->magnitude_scale = cd.s * m.samples->scale;
    report->magnitude_step = cd.step_m;
    report->shape_step = cd.step_c;
    double sum2 = 0;
    std::uint64_t count = 0;
    for (std::size_t cell = 0; cell < kMerlCells; ++cell) {
      if (g.brdf[cell] < 0 || ref.brdf[cell] < 0) continue;
      ++report->valid_cells;
      for (std::size_t b = 0; b < cd.bands; ++b) {
        const double d = (double(g.brdf[b * kMerlCells + cell]) - double(ref.brdf[b * kMerlCells + cell])) * ref.scale;
        report->max_abs_error = std::max(report->max_abs_error, std::abs(d));
        sum2 += d * d;
        ++count;
      }
    }
    report->rms_error = count ? std::sqrt(sum2 / double(count)) : 0.0;
  }
  return out;
}

SpcCoefficients decode_samples(std::span<const std::uint8_t> bytes, const std::string& label, bool header_only) {
  Reader r(bytes.first(bytes.size() - 4), label);
  r.take(sizeof kSpcMagic + 4, "magic and version");
  const auto [bands, k] = read_shape(r, label);
  SpcCoefficients c;
  c.scale = r.get<double>("scale");
  const double s = r.get<double>("magnitude scale");
  for (const auto& [v, what] : {std::pair{c.scale, "scale"}, std::pair{s, "magnitude scale"}})
    if (!(std::isfinite(v) && v > 0))
      throw InputError(label + ": .spc header field '" + what + "' is " + std::to_string(v) +
                       "; it must be finite and positive");
  std::vector<double> wl(bands);
  std::memcpy(wl.data(), r.take(8 * std::size_t(bands), "wavelengths"), 8 * std::size_t(bands));
  c.wavelengths = checked_wavelengths(std::move(wl), label);
  c.basis = read_basis<float>(r, k, bands, label);
  c.units = r.string("units");
  c.source = r.string("source");
  c.reference = r.string("basis reference");
  if (header_only) return c;
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
  SampleCodes cd{.n = r.get<std::uint32_t>("samples"), .k = k, .bands = bands};
  cd.s = s;
  cd.angle_step = r.get<double>("angle step");
  cd.step_m = r.get<double>("magnitude step");
  cd.step_c = r.get<double>("shape step");
  if (cd.n == 0 || cd.n > kMaxSamples)
    throw InputError(label + ": .spc holds " + std::to_string(cd.n) + " samples; 1 to 2^24 are valid");
  for (const auto& [v, what] : {std::pair{cd.angle_step, "angle step"}, std::pair{cd.step_m, "magnitude step"},
                                std::pair{cd.step_c, "shape step"}})
    if (!(std::isfinite(v) && v > 0 && v <= 1e3))
      throw InputError(label + ": .spc field '" + what + "' is " + std::to_string(v) + "; it must be in (0, 1000]");
  const char* names[3] = {"angles", "magnitudes", "shapes"};
  std::vector<std::uint8_t> raw[3];
  for (int i = 0; i < 3; ++i) {
    const auto raw_size = r.get<std::uint32_t>(names[i]), z = r.get<std::uint32_t>(names[i]);
    const std::size_t least = i == 0 ? 4 * std::size_t(cd.n) : i == 1 ? cd.n : std::size_t(cd.n) * k;
    if (raw_size < least || raw_size > 10 * (least + 8 * std::size_t(cd.n) + 64))
      throw InputError(label + ": .spc " + names[i] + " stream claims " + std::to_string(raw_size) + " bytes for " +
                       std::to_string(cd.n) + " samples");
    raw[i].resize(raw_size);
    zstd_decompress(r.take(z, names[i]), z, raw[i], label, names[i]);
  }
  cd.angles = get_angle_columns(raw[0], cd.n, label);
  cd.mag = get_varints(raw[1], cd.n, label, names[1]);
  const std::vector<std::int64_t> shapes = get_varints(raw[2], std::size_t(cd.n) * k, label, names[2]);
  cd.shape.resize(shapes.size());
  for (std::size_t j = 0; j < k; ++j)
    for (std::size_t i = 0; i < cd.n; ++i) cd.shape[i * k + j] = shapes[j * cd.n + i];
  for (const auto* v : {&cd.angles, &cd.mag, &cd.shape})
    for (const auto x : *v)
      if (x <= -kMaxSampleCode || x >= kMaxSampleCode) throw InputError(label + ": .spc holds a code beyond +-2^27");
  for (const auto q : cd.mag)
    if (double(q) * cd.step_m > 700) throw InputError(label + ": .spc holds a magnitude beyond a double's range");
  for (const auto q : cd.angles)
    if (!(std::abs(double(q) * cd.angle_step) <= kMaxAngle))
      throw InputError(label + ": .spc holds an angle beyond +-4 pi");
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
