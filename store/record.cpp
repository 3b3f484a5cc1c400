// Records: objects of kinds other libraries define (acquire's calibrations), as named float64 arrays and texts.
#include <algorithm>
#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/detail/objects.h"

namespace specula::store {
namespace {

constexpr std::string_view kProvenanceAttributes[] = {"source_file", "importer", "specula_version", "command_line",
                                                      "created_utc"};

template <class T>
const T& field(const std::vector<std::pair<std::string, T>>& fields, std::string_view name, const std::string& label,
               const char* what) {
  for (const auto& [n, v] : fields)
    if (n == name) return v;
  throw InputError(label + ": " + what + " '" + std::string(name) + "' is missing");
}

// Names of the attributes of `obj`, in creation order.
std::vector<std::string> attribute_names(hid_t obj, const std::string& ctx) {
  H5O_info_t info{};
#if H5_VERSION_GE(1, 12, 0)
  h5::check(H5Oget_info3(obj, &info, H5O_INFO_NUM_ATTRS), ctx, "H5Oget_info");
#else
  h5::check(H5Oget_info2(obj, &info, H5O_INFO_NUM_ATTRS), ctx, "H5Oget_info");
#endif
  std::vector<std::string> names;
  for (hsize_t i = 0; i < info.num_attrs; ++i) {
    const ssize_t n = H5Aget_name_by_idx(obj, ".", H5_INDEX_NAME, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
    h5::check(n, ctx, "H5Aget_name_by_idx");
    std::string name(std::size_t(n) + 1, '\0');
    h5::check(H5Aget_name_by_idx(obj, ".", H5_INDEX_NAME, H5_ITER_INC, i, name.data(), name.size(), H5P_DEFAULT), ctx,
              "H5Aget_name_by_idx");
    name.resize(std::size_t(n));
    names.push_back(std::move(name));
  }
  return names;
}

}  // namespace

const Eigen::MatrixXd& Record::matrix(std::string_view name) const { return field(matrices, name, label, "matrix"); }
const std::vector<double>& Record::vector(std::string_view name) const { return field(vectors, name, label, "vector"); }
const std::string& Record::text(std::string_view name) const { return field(texts, name, label, "attribute"); }

std::vector<std::string> Store::objects(std::string_view kind) const {
  return h5::list(StoreAccess::root(*this), "/" + std::string(kind));
}

std::string Store::created_utc() const {
  const hid_t root = StoreAccess::root(*this);
  return h5::has_attr(root, "created_utc") ? h5::read_string_attr(root, "created_utc", label()) : "";
}

Record Store::read_record(const std::string& kind, const std::string& name) const {
  const std::string path = "/" + kind + "/" + name;
  const hid_t root = StoreAccess::root(*this);
  if (name.empty() || name.find('/') != std::string::npos || !h5::exists(root, "/" + kind) || !h5::exists(root, path))
    throw InputError(label() + ": no " + kind + " object '" + name + "' (" + kind + ": " + join(objects(kind)) + ")");
  Record r;
  r.label = label() + ": " + path;
  h5::Id g = open_group(root, path, r.label);
  for (const auto& member : h5::list(root, path)) {
    h5::Id ds = open_dataset(g, member, r.label);
    const auto dims = h5::shape(ds, r.label);
    if (dims.size() == 1)
      r.vectors.emplace_back(member, h5::read_vector(g, member, r.label));
    else if (dims.size() == 2)
      r.matrices.emplace_back(member, h5::read_matrix(g, member, r.label));
    else
      throw InputError(r.label + "/" + member + ": a record holds 1-D and 2-D datasets, this one has " +
                       std::to_string(dims.size()) + " dimensions");
  }
  for (const auto& a : attribute_names(g, r.label))
    if (std::find(std::begin(kProvenanceAttributes), std::end(kProvenanceAttributes), a) ==
        std::end(kProvenanceAttributes))
      r.texts.emplace_back(a, h5::read_string_attr(g, a, r.label));
  r.provenance = read_provenance(g, r.label);
  return r;
}

void StoreWriter::add_record(const std::string& kind, const std::string& name, const Record& record) {
  if (!layout::is_kind(kind) || kind == "images" || kind == "collections" || kind == "samples" || kind == "grids" ||
      kind == "bases" || kind == "coefficients")
    throw UsageError(label() + ": '" + kind + "' is not a kind of record (use acquire, or the add_ functions)");
  const std::string path = "/" + kind + "/" + name, ctx = label() + ": " + path;
  h5::Id g = make_group(begin(kind, name, kind), path, ctx);
  for (const auto& [n, m] : record.matrices) h5::write_matrix(g, n, m, ctx);
  for (const auto& [n, v] : record.vectors) h5::write_vector(g, n, v, ctx);
  for (const auto& [n, t] : record.texts) h5::write_attr(g, n, std::string_view(t), ctx);
  write_provenance(g, record.provenance, options_.command_line, ctx);
}

}  // namespace specula::store
