#include "specula/acquire/capture.h"

#include <nlohmann/json.hpp>

#include <fstream>
#include <set>
#include <tuple>

#include "specula/acquire/filters.h"
#include "specula/core/atomic_file.h"
#include "specula/core/error.h"

namespace specula::acquire {

using nlohmann::json;
namespace fs = std::filesystem;

std::string kind_name(ImageKind k) {
  switch (k) {
    case ImageKind::scene:
      return "scene";
    case ImageKind::silhouette:
      return "silhouette";
    case ImageKind::mirror:
      return "mirror";
    case ImageKind::flat:
      return "flat";
    case ImageKind::target:
      return "target";
    case ImageKind::holdout:
      return "holdout";
  }
  return "?";
}

ImageKind parse_kind(const std::string& name, const std::string& context) {
  for (const ImageKind k : {ImageKind::scene, ImageKind::silhouette, ImageKind::mirror, ImageKind::flat,
                            ImageKind::target, ImageKind::holdout})
    if (kind_name(k) == name) return k;
  throw InputError(context + ": unknown image kind '" + name + "' (scene, silhouette, mirror, flat, target, holdout)");
}

void write_manifest(const fs::path& dir, const Capture& c) {
  json j;
  j["format"] = kCaptureFormat;
  j["version"] = kCaptureVersion;
  j["description"] = c.description;
  j["camera"] = {{"width", c.width},       {"height", c.height}, {"bit_depth", c.bit_depth},
                 {"focal_px", c.focal_px}, {"cx", c.cx},         {"cy", c.cy}};
  j["rig"] = {{"sphere_radius_m", c.sphere_radius_m}, {"light_distance_m", c.light_distance_m}};
  j["bands_nm"] = c.bands;
  j["light_angles_deg"] = c.light_angles_deg;
  j["light_spectrum"] = {{"nm", c.light_spectrum_nm}, {"value", c.light_spectrum}};
  j["lctf_transmission"] = json::array();
  for (std::size_t b = 0; b < c.lctf_nm.size(); ++b)
    j["lctf_transmission"].push_back({{"nm", c.lctf_nm[b]}, {"value", c.lctf_value[b]}});
  if (c.filters)
    j["filters"] = {{"names", c.filters->names}, {"nm", c.filters->nm}, {"transmission", c.filters->transmission}};
  j["targets"] = json::array();
  for (const auto& t : c.targets) j["targets"].push_back({{"name", t.name}, {"reflectance", t.reflectance}});
  if (!c.holdout.empty()) {
    j["holdout_patches"] = json::array();
    for (const auto& p : c.holdout)
      j["holdout_patches"].push_back(
          {{"name", p.name}, {"reflectance", p.reflectance}, {"region_px", {p.u0, p.v0, p.u1, p.v1}}});
  }
  j["images"] = json::array();
  for (const auto& im : c.images) {
    json e = {{"file", im.file}, {"kind", kind_name(im.kind)}, {"exposure_s", im.exposure_s}};
    if (im.light >= 0) e["light"] = im.light;
    if (im.band >= 0) e[c.filters ? "filter" : "band"] = im.band;
    if (im.target >= 0) e["target"] = im.target;
    j["images"].push_back(e);
  }
  if (c.truth)
    j["truth"] = {{"sphere_centre_m", c.truth->sphere_centre},
                  {"sphere_radius_m", c.truth->sphere_radius},
                  {"light_dirs", c.truth->light_dirs},
                  {"material", c.truth->material}};
  AtomicOutput out(dir / "manifest.json");
  {
    std::ofstream f(out.temp_path());
    f << j.dump(1) << "\n";
    if (!f) throw LibraryError(out.temp_path().string() + ": cannot write the manifest");
  }
  out.commit();
}

namespace {

template <class T>
T field(const json& j, const char* key, const std::string& ctx) {
  if (!j.contains(key)) throw InputError(ctx + ": missing \"" + key + "\"");
  try {
    return j.at(key).get<T>();
  } catch (const json::exception&) {
    throw InputError(ctx + ": \"" + key + "\" has the wrong type");
  }
}

// One entry of the manifest's "images", checked against the capture's lights, bands and targets read so far and the
// directory's files.
CaptureImage read_image_entry(const json& e, const Capture& c, const fs::path& dir, const std::string& ctx) {
  CaptureImage im;
  im.file = field<std::string>(e, "file", ctx + " image");
  const std::string ictx = ctx + ": image '" + im.file + "'";
  im.kind = parse_kind(field<std::string>(e, "kind", ictx), ictx);
  im.exposure_s = field<double>(e, "exposure_s", ictx);
  im.light = e.value("light", -1);
  im.band = e.value(c.filters ? "filter" : "band", -1);
  im.target = e.value("target", -1);
  if (im.file.empty() || fs::path(im.file).is_absolute() || im.file.find("..") != std::string::npos)
    throw InputError(ictx + ": the file must be a path inside the capture directory");
  if (!(im.exposure_s > 0)) throw InputError(ictx + ": exposure_s must be positive");
  const bool needs_light = im.kind == ImageKind::scene || im.kind == ImageKind::mirror;
  const bool needs_band = im.kind == ImageKind::scene || im.kind == ImageKind::flat || im.kind == ImageKind::target ||
                          im.kind == ImageKind::holdout;
  if (needs_light != (im.light >= 0) || im.light >= int(c.light_angles_deg.size()))
    throw InputError(ictx + ": light " + std::to_string(im.light) + " is not one of the " +
                     std::to_string(c.light_angles_deg.size()) + " light positions a " + kind_name(im.kind) +
                     " image needs");
  const char* channel = c.filters ? "filter" : "band";
  if (needs_band != (im.band >= 0) || im.band >= int(c.channels()))
    throw InputError(ictx + ": " + channel + " " + std::to_string(im.band) + " is not one of the " +
                     std::to_string(c.channels()) + " " + channel + "s a " + kind_name(im.kind) + " image needs");
  if ((im.kind == ImageKind::target) != (im.target >= 0) || im.target >= int(c.targets.size()))
    throw InputError(ictx + ": target " + std::to_string(im.target) + " is not one of the " +
                     std::to_string(c.targets.size()) + " targets");
  if (!fs::is_regular_file(dir / im.file)) throw InputError(ictx + ": file is missing from " + dir.string());
  return im;
}

// The manifest's "filters" entry (format 2): names, wavelengths and curves, checked against the bands.
FilterSet read_manifest_filters(const json& fj, const std::vector<double>& bands, const std::string& ctx) {
  FilterSet f;
  f.names = field<std::vector<std::string>>(fj, "names", ctx + " filters");
  f.nm = field<std::vector<double>>(fj, "nm", ctx + " filters");
  f.transmission = field<std::vector<std::vector<double>>>(fj, "transmission", ctx + " filters");
  for (std::size_t i = 1; i < f.nm.size(); ++i)
    if (!(f.nm[i] > f.nm[i - 1])) throw InputError(ctx + ": \"filters\" wavelengths must increase");
  if (f.names.size() != f.transmission.size())
    throw InputError(ctx + ": \"filters\" has " + std::to_string(f.names.size()) + " names for " +
                     std::to_string(f.transmission.size()) + " curves");
  check_filters(f, bands, ctx + " filters");
  return f;
}

// The manifest's "holdout_patches" entry (format 3): names, reflectance on the bands, regions on the image.
std::vector<HoldoutPatch> read_holdout_patches(const json& hj, const Capture& c, const std::string& ctx) {
  std::vector<HoldoutPatch> patches;
  for (const json& e : hj) {
    HoldoutPatch p{field<std::string>(e, "name", ctx + " holdout_patches"),
                   field<std::vector<double>>(e, "reflectance", ctx + " holdout_patches")};
    const std::string pctx = ctx + ": held-out patch '" + p.name + "'";
    if (p.reflectance.size() != c.bands.size())
      throw InputError(pctx + " has " + std::to_string(p.reflectance.size()) + " reflectance values for " +
                       std::to_string(c.bands.size()) + " bands");
    const auto region = field<std::vector<int>>(e, "region_px", pctx);
    if (region.size() != 4 || region[0] < 0 || region[1] < 0 || region[2] > c.width || region[3] > c.height ||
        region[0] >= region[2] || region[1] >= region[3])
      throw InputError(pctx +
                       ": \"region_px\" must be [u0, v0, u1, v1] with 0 <= u0 < u1 <= width, 0 <= v0 < v1 <= height");
    p.u0 = region[0], p.v0 = region[1], p.u1 = region[2], p.v1 = region[3];
    patches.push_back(std::move(p));
  }
  return patches;
}

}  // namespace

Capture read_manifest(const fs::path& dir) {
  const fs::path path = dir / "manifest.json";
  const std::string ctx = path.string();
  std::ifstream f(path);
  if (!f) throw InputError(ctx + ": cannot open the capture's manifest (is " + dir.string() + " a capture directory?)");
  json j;
  try {
    j = json::parse(f);
  } catch (const json::parse_error& e) {
    throw InputError(ctx + ": not valid JSON (" + std::string(e.what()) + ")");
  }
  if (!j.is_object() || field<std::string>(j, "format", ctx) != kCaptureFormat)
    throw InputError(ctx + ": not a specula capture manifest (\"format\" must be \"" + kCaptureFormat + "\")");
  const int version = field<int>(j, "version", ctx);
  if (version < 1 || version > kCaptureVersion)
    throw InputError(ctx + ": capture format version " + std::to_string(version) + "; this specula reads 1 to " +
                     std::to_string(kCaptureVersion));
  Capture c;
  c.description = j.value("description", "");
  const json cam = field<json>(j, "camera", ctx);
  c.width = field<int>(cam, "width", ctx + " camera");
  c.height = field<int>(cam, "height", ctx + " camera");
  c.bit_depth = field<int>(cam, "bit_depth", ctx + " camera");
  c.focal_px = field<double>(cam, "focal_px", ctx + " camera");
  c.cx = field<double>(cam, "cx", ctx + " camera");
  c.cy = field<double>(cam, "cy", ctx + " camera");
  if (c.width <= 0 || c.height <= 0 || c.width > 65536 || c.height > 65536)
    throw InputError(ctx + ": camera size must be 1 to 65536 pixels a side");
  if (c.bit_depth < 8 || c.bit_depth > 16) throw InputError(ctx + ": camera bit_depth must be 8 to 16");
  if (!(c.focal_px > 0)) throw InputError(ctx + ": camera focal_px must be positive");
  if (j.contains("rig")) {
    c.sphere_radius_m = j["rig"].value("sphere_radius_m", 0.0);
    c.light_distance_m = j["rig"].value("light_distance_m", 0.0);
    if (!(c.sphere_radius_m >= 0) || !(c.light_distance_m >= 0))
      throw InputError(ctx + ": rig sphere_radius_m and light_distance_m must be >= 0 (0: unknown)");
  }
  c.bands = field<std::vector<double>>(j, "bands_nm", ctx);
  if (c.bands.empty()) throw InputError(ctx + ": \"bands_nm\" is empty");
  for (std::size_t i = 1; i < c.bands.size(); ++i)
    if (!(c.bands[i] > c.bands[i - 1])) throw InputError(ctx + ": \"bands_nm\" must increase");
  c.light_angles_deg = field<std::vector<double>>(j, "light_angles_deg", ctx);
  const json spd = field<json>(j, "light_spectrum", ctx);
  c.light_spectrum_nm = field<std::vector<double>>(spd, "nm", ctx + " light_spectrum");
  c.light_spectrum = field<std::vector<double>>(spd, "value", ctx + " light_spectrum");
  if (c.light_spectrum_nm.size() != c.light_spectrum.size() || c.light_spectrum.size() < 2)
    throw InputError(ctx + ": \"light_spectrum\" needs as many values as wavelengths, at least 2");
  if (j.contains("lctf_transmission")) {
    for (const json& t : j["lctf_transmission"]) {
      c.lctf_nm.push_back(field<std::vector<double>>(t, "nm", ctx + " lctf_transmission"));
      c.lctf_value.push_back(field<std::vector<double>>(t, "value", ctx + " lctf_transmission"));
      if (c.lctf_nm.back().size() != c.lctf_value.back().size() || c.lctf_nm.back().size() < 2)
        throw InputError(ctx + ": each \"lctf_transmission\" curve needs as many values as wavelengths, at least 2");
    }
    if (!c.lctf_nm.empty() && c.lctf_nm.size() != c.bands.size())
      throw InputError(ctx + ": \"lctf_transmission\" has " + std::to_string(c.lctf_nm.size()) + " curves for " +
                       std::to_string(c.bands.size()) + " bands");
  }
  if (j.contains("filters")) {
    if (version < 2) throw InputError(ctx + ": \"filters\" needs capture format version 2");
    c.filters = read_manifest_filters(j["filters"], c.bands, ctx);
  }
  for (const json& t : field<json>(j, "targets", ctx)) {
    CaptureTarget target{field<std::string>(t, "name", ctx + " target"),
                         field<std::vector<double>>(t, "reflectance", ctx + " target")};
    if (target.reflectance.size() != c.bands.size())
      throw InputError(ctx + ": target '" + target.name + "' has " + std::to_string(target.reflectance.size()) +
                       " reflectance values for " + std::to_string(c.bands.size()) + " bands");
    c.targets.push_back(std::move(target));
  }
  if (j.contains("holdout_patches")) {
    if (version < 3) throw InputError(ctx + ": \"holdout_patches\" needs capture format version 3");
    c.holdout = read_holdout_patches(j["holdout_patches"], c, ctx);
  }
  std::set<std::tuple<int, int, double>> scene_exposures;
  std::set<int> holdout_channels;
  for (const json& e : field<json>(j, "images", ctx)) {
    CaptureImage im = read_image_entry(e, c, dir, ctx);
    if (im.kind == ImageKind::scene && !scene_exposures.insert({im.light, im.band, im.exposure_s}).second)
      throw InputError(ctx + ": image '" + im.file + "': a second image for the same light, band and exposure");
    if (im.kind == ImageKind::holdout) {
      if (c.holdout.empty())
        throw InputError(ctx + ": image '" + im.file + "' is a holdout image but there are no \"holdout_patches\"");
      holdout_channels.insert(im.band);
    }
    c.images.push_back(std::move(im));
  }
  if (!c.holdout.empty() && holdout_channels.size() != c.channels())
    throw InputError(ctx + ": \"holdout_patches\" needs holdout images in every one of the " +
                     std::to_string(c.channels()) + " channels; " + std::to_string(holdout_channels.size()) +
                     " have them");
  for (int l = 0; l < int(c.light_angles_deg.size()); ++l)
    for (int b = 0; b < int(c.channels()); ++b) {
      const auto it = scene_exposures.lower_bound({l, b, 0.0});
      if (it == scene_exposures.end() || std::get<0>(*it) != l || std::get<1>(*it) != b)
        throw InputError(ctx + ": no scene exposure for light " + std::to_string(l) +
                         (c.filters ? " through filter '" + c.filters->names[std::size_t(b)] + "'"
                                    : " at " + std::to_string(int(c.bands[std::size_t(b)])) + " nm"));
    }
  if (j.contains("truth")) {
    const json& t = j["truth"];
    CaptureTruth truth;
    truth.sphere_centre = field<std::vector<double>>(t, "sphere_centre_m", ctx + " truth");
    truth.sphere_radius = field<double>(t, "sphere_radius_m", ctx + " truth");
    truth.light_dirs = field<std::vector<std::vector<double>>>(t, "light_dirs", ctx + " truth");
    truth.material = t.value("material", "");
    c.truth = truth;
  }
  return c;
}

}  // namespace specula::acquire
