// The "priors" object kind (docs/store-format.md): a learned BRDF prior's tables (store/prior.h).
#include "specula/store/prior.h"

#include <algorithm>
#include <cmath>

#include "specula/core/error.h"
#include "specula/core/parallel.h"
#include "specula/store/detail/deflate.h"
#include "specula/store/detail/objects.h"

namespace specula::store {
namespace {

// 2: `ceiling` added (a prior without it is written, and read, as version 1). 3: `retro_exponents` added (a prior
// with a ceiling but without them is written, and read, as version 2). 4: `retro_rise` added (a prior with exponents
// but without it is written, and read, as version 3).
constexpr long long kPriorVersion = 4;

// A rows x cols float32 dataset, chunked by rows of at most 2^18 values and deflated.
void write_f32(hid_t loc, const std::string& name, std::span<const float> v, hsize_t rows, const std::string& ctx) {
  const hsize_t cols = rows ? hsize_t(v.size()) / rows : 0;
  const hsize_t dims[2] = {rows, cols};
  h5::Id space(h5::check(H5Screate_simple(2, dims, nullptr), ctx, "H5Screate_simple"));
  h5::Id dcpl(h5::check(H5Pcreate(H5P_DATASET_CREATE), ctx, "H5Pcreate"));
  if (rows && cols) {
    const hsize_t chunk[2] = {1, std::min<hsize_t>(cols, hsize_t(1) << 18)};
    h5::check(H5Pset_chunk(dcpl, 2, chunk), ctx, "H5Pset_chunk");
    h5::check(H5Pset_shuffle(dcpl), ctx, "H5Pset_shuffle");
    h5::check(H5Pset_deflate(dcpl, 4), ctx, "H5Pset_deflate");
  }
  h5::Id ds(h5::check(H5Dcreate2(loc, name.c_str(), H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), ctx,
                      "cannot create " + name));
  if (!v.empty())
    h5::check(H5Dwrite(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), ctx, "cannot write " + name);
}

// Dataset `name` of loc, checked to be rows x cols.
h5::Id open_f32(hid_t loc, const std::string& name, hsize_t rows, hsize_t cols, const std::string& ctx) {
  if (!h5::exists(loc, name)) throw InputError(ctx + ": dataset '" + name + "' is missing");
  h5::Id ds(h5::check(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), ctx, "cannot open " + name));
  const auto dims = h5::shape(ds, ctx);
  if (dims != std::vector<hsize_t>{rows, cols})
    throw InputError(ctx + ": dataset '" + name + "' is not " + std::to_string(rows) + " x " + std::to_string(cols));
  return ds;
}

void check_finite(std::span<const float> v, const std::string& name, const std::string& ctx) {
  for (const float x : v)
    if (!std::isfinite(x)) throw InputError(ctx + ": dataset '" + name + "' holds a non-finite value");
}

std::vector<float> read_f32(hid_t loc, const std::string& name, hsize_t rows, hsize_t cols, const std::string& ctx) {
  h5::Id ds = open_f32(loc, name, rows, cols, ctx);
  std::vector<float> v(rows * cols);
  if (!v.empty())
    h5::check(H5Dread(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), ctx, "cannot read " + name);
  check_finite(v, name, ctx);
  return v;
}

// How a prior's components are stored: chunks of (1, cols) with filters decode_chunk undoes, or (cols 0) not
// readable chunk by chunk here (HDF5 decodes them).
struct ComponentChunks {
  ChunkFilters filters;
  std::size_t cols = 0;
};

ComponentChunks component_chunks(hid_t ds, const std::string& ctx) {
  h5::Id dcpl(h5::check(H5Dget_create_plist(ds), ctx, "H5Dget_create_plist"));
  if (H5Pget_layout(dcpl) != H5D_CHUNKED) return {};
  const ChunkFilters filters = chunk_filters(dcpl);
  hsize_t dims[2] = {0, 0};
  if (!filters.known || H5Pget_chunk(dcpl, 2, dims) != 2 || dims[0] != 1) return {};
  return {filters, std::size_t(dims[1])};
}

// Rows x cells [first, first + count) of the components into out, their chunks read raw (H5Dread_chunk) in batches
// and decoded on every thread; first and count cover whole chunks (count may end at the last cell).
void read_component_chunks(hid_t ds, const ComponentChunks& cc, std::size_t rows, std::size_t first, std::size_t count,
                           std::span<float> out, const std::string& ctx) {
  const std::size_t per_row = (count + cc.cols - 1) / cc.cols, chunks = rows * per_row;
  const std::size_t batch = 8 * std::size_t(std::max(1, omp_get_max_threads()));
  std::vector<std::vector<unsigned char>> raw(batch);
  std::vector<std::uint32_t> skipped(batch);
  for (std::size_t c0 = 0; c0 < chunks; c0 += batch) {
    const std::size_t n = std::min(batch, chunks - c0);
    for (std::size_t j = 0; j < n; ++j) {
      const hsize_t at[2] = {(c0 + j) / per_row, first + (c0 + j) % per_row * cc.cols};
      hsize_t bytes = 0;
      h5::check(H5Dget_chunk_storage_size(ds, at, &bytes), ctx, "H5Dget_chunk_storage_size");
      if (bytes == 0) throw InputError(ctx + ": a chunk of dataset 'components' was never written");
      raw[j].resize(bytes);
      h5::check(H5Dread_chunk(ds, H5P_DEFAULT, at, &skipped[j], raw[j].data()), ctx, "cannot read a chunk");
    }
    parallel_for(n, [&](std::size_t j) {
      const std::size_t q = (c0 + j) / per_row, x0 = (c0 + j) % per_row * cc.cols;
      const float* v = decode_chunk(raw[j].data(), raw[j].size(), cc.filters.deflated(skipped[j]),
                                    cc.filters.shuffled(skipped[j]), cc.cols * sizeof(float));
      if (!v) throw InputError(ctx + ": a chunk of dataset 'components' is corrupt");
      const std::span<const float> values(v, std::min(cc.cols, count - x0));
      check_finite(values, "components", ctx);
      std::ranges::copy(values, out.begin() + std::ptrdiff_t(q * count + x0));
    });
  }
}

// The group of prior `name`, its version checked; InputError listing the store's priors when absent.
h5::Id open_prior(const Store& s, const std::string& name, const std::string& ctx) {
  const hid_t root = StoreAccess::root(s);
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(root, "/priors") ||
      !h5::exists(root, "/priors/" + name))
    throw InputError(s.label() + ": no prior '" + name + "' (priors: " + join(s.objects("priors")) +
                     "; build one with specula prior build)");
  h5::Id g = open_group(root, "/priors/" + name, ctx);
  const long long version = h5::read_int_attr(g, "prior_version", ctx);
  if (version > kPriorVersion)
    throw InputError(ctx + ": prior version " + std::to_string(version) + " is newer than this specula reads (" +
                     std::to_string(kPriorVersion) + "); upgrade specula");
  return g;
}

}  // namespace

std::size_t retro_rise_values(std::size_t widths) {
  std::size_t n = 0;
  for (std::size_t w = 1; w <= widths; ++w) n += 2 * w * w;
  return n;
}

void StoreWriter::add_prior(const std::string& name, const PriorTables& p) {
  const std::string path = "/priors/" + name, ctx = label() + ": " + path;
  const std::size_t k = p.variances.size(), cells = p.mean.size();
  if (p.reference.size() != cells || !(p.ceiling.empty() || p.ceiling.size() == cells) ||
      (p.components.empty() ? k && !p.component_blocks : p.components.size() != k * cells))
    throw UsageError(ctx +
                     ": reference, mean, ceiling and components (k x cells, or made by component_blocks) disagree");
  h5::Id g = make_group(begin("priors", name, "prior"), path, ctx);
  if (p.ceiling.empty() && !p.retro_exponents.empty())
    throw UsageError(ctx + ": a prior with retro exponents needs its ceiling (version 3 keeps both)");
  if (!p.retro_rise.empty() && p.retro_rise.size() != retro_rise_values(p.retro_exponents.size()))
    throw UsageError(ctx + ": a prior's retro rise maps need its exponents, 2 w^2 values for each of their widths w");
  h5::write_attr(g, "prior_version",
                 p.ceiling.empty()           ? 1
                 : p.retro_exponents.empty() ? 2
                 : p.retro_rise.empty()      ? 3
                                             : kPriorVersion,
                 ctx);
  h5::write_attr(g, "mapping", std::string_view("log-relative-cos"), ctx);
  h5::write_attr(g, "epsilon", p.epsilon, ctx);
  h5::write_vector(g, "wavelengths", p.wavelengths, ctx);
  h5::write_vector(g, "knots", p.knots, ctx);
  h5::write_vector(g, "variances", p.variances, ctx);
  write_f32(g, "reference", p.reference, 1, ctx);
  write_f32(g, "mean", p.mean, 1, ctx);
  if (!p.ceiling.empty()) write_f32(g, "ceiling", p.ceiling, 1, ctx);
  if (!p.retro_exponents.empty()) h5::write_vector(g, "retro_exponents", p.retro_exponents, ctx);
  if (!p.retro_rise.empty()) h5::write_vector(g, "retro_rise", p.retro_rise, ctx);
  const hsize_t dims[2] = {k, cells};
  h5::Id space(h5::check(H5Screate_simple(2, dims, nullptr), ctx, "H5Screate_simple"));
  h5::Id dcpl(h5::check(H5Pcreate(H5P_DATASET_CREATE), ctx, "H5Pcreate"));
  if (k && cells) {
    const hsize_t chunk[2] = {1, std::min<hsize_t>(cells, kPriorBlockCells)};
    h5::check(H5Pset_chunk(dcpl, 2, chunk), ctx, "H5Pset_chunk");
    h5::check(H5Pset_shuffle(dcpl), ctx, "H5Pset_shuffle");
    h5::check(H5Pset_deflate(dcpl, 4), ctx, "H5Pset_deflate");
  }
  h5::Id ds(h5::check(H5Dcreate2(g, "components", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), ctx,
                      "cannot create components"));
  std::vector<float> block;
  for (std::size_t first = 0; k && first < cells; first += kPriorBlockCells) {  // whole chunks, each written once
    const std::size_t count = std::min(kPriorBlockCells, cells - first);
    block.assign(k * count, 0.0f);
    if (p.components.empty()) {
      p.component_blocks(first, count, block);
    } else {
      for (std::size_t q = 0; q < k; ++q)
        std::copy_n(p.components.begin() + std::ptrdiff_t(q * cells + first), count,
                    block.begin() + std::ptrdiff_t(q * count));
    }
    for (const float x : block)
      if (!std::isfinite(x)) throw InputError(ctx + ": a non-finite component value");
    const hsize_t start[2] = {0, first}, cnt[2] = {k, count};
    write_hyperslab(ds, H5T_NATIVE_FLOAT, start, cnt, block.data(), ctx);
  }
  std::string list;
  for (const auto& t : p.training) list += (list.empty() ? "" : "\n") + t;
  h5::write_attr(g, "training", std::string_view(list), ctx);
  Provenance prov;
  prov.importer = "prior build";
  prov.command_line = p.command_line;
  write_provenance(g, prov, options_.command_line, ctx);
}

PriorTables Store::read_prior(const std::string& name, std::size_t cells, bool components) const {
  const std::string ctx = label() + ": /priors/" + name;
  h5::Id g = open_prior(*this, name, ctx);
  PriorTables p;
  p.wavelengths = h5::read_vector(g, "wavelengths", ctx);
  p.knots = h5::read_vector(g, "knots", ctx);
  p.variances = h5::read_vector(g, "variances", ctx);
  p.epsilon = read_double_attr(g, "epsilon", ctx);
  p.reference = read_f32(g, "reference", 1, cells, ctx);
  p.mean = read_f32(g, "mean", 1, cells, ctx);
  const long long version = h5::read_int_attr(g, "prior_version", ctx);
  if (version >= 2) p.ceiling = read_f32(g, "ceiling", 1, cells, ctx);
  if (version >= 3) p.retro_exponents = h5::read_vector(g, "retro_exponents", ctx);
  if (version >= 4) p.retro_rise = h5::read_vector(g, "retro_rise", ctx);
  if (components)
    p.components = read_f32(g, "components", p.variances.size(), cells, ctx);
  else
    open_f32(g, "components", p.variances.size(), cells, ctx);
  const std::string list = h5::read_string_attr(g, "training", ctx);
  for (std::size_t at = 0; at < list.size();) {
    const std::size_t nl = std::min(list.find('\n', at), list.size());
    p.training.push_back(list.substr(at, nl - at));
    at = nl + 1;
  }
  if (p.knots.size() < 2 || !(p.epsilon > 0) ||
      std::any_of(p.variances.begin(), p.variances.end(), [](double v) { return !(v > 0); }) ||
      std::any_of(p.ceiling.begin(), p.ceiling.end(), [](float c) { return c < 0; }) ||
      (version >= 3 && p.retro_exponents.empty()) ||
      std::any_of(p.retro_exponents.begin(), p.retro_exponents.end(),
                  [](double e) { return !(e > 0) || !std::isfinite(e); }) ||
      (version >= 4 && p.retro_rise.size() != retro_rise_values(p.retro_exponents.size())) ||
      std::any_of(p.retro_rise.begin(), p.retro_rise.end(), [](double e) { return !std::isfinite(e); }))
    throw InputError(ctx +
                     ": malformed prior (knots, epsilon, variances, a negative ceiling, retro exponents or rise maps)");
  return p;
}

void Store::read_prior_components(const std::string& name, std::size_t first, std::size_t count,
                                  std::span<float> out) const {
  const std::string ctx = label() + ": /priors/" + name;
  h5::Id g = open_prior(*this, name, ctx);
  h5::Id ds = open_dataset(g, "components", ctx);
  const auto dims = h5::shape(ds, ctx);
  if (dims.size() != 2) throw InputError(ctx + ": dataset 'components' is not k x cells");
  if (first > dims[1] || count > dims[1] - first || out.size() != dims[0] * count)
    throw UsageError(ctx + ": read_prior_components range or buffer size is wrong");
  if (out.empty()) return;
  const ComponentChunks cc = component_chunks(ds, ctx);
  if (cc.cols && first % cc.cols == 0 && (count % cc.cols == 0 || first + count == dims[1])) {
    read_component_chunks(ds, cc, dims[0], first, count, out, ctx);  // checked chunk by chunk
  } else {
    const hsize_t start[2] = {0, first}, cnt[2] = {dims[0], count};
    read_hyperslab(ds, H5T_NATIVE_FLOAT, start, cnt, out.data(), ctx);
    check_finite(out, "components", ctx);
  }
}

}  // namespace specula::store
