#pragma once
// Minimal scenes that render an RGL material on a sphere under an environment: pbrt-v4 (spectral files only) and
// Mitsuba 3 (a spectral variant for spectral files, an RGB variant for RGB files).
#include <filesystem>
#include <string>

namespace specula::codec {

/// A pbrt-v4 scene: the material file `bsdf` (a name relative to the scene) on a unit sphere seen from +z, a uniform
/// sky and a distant sun, writing `image`.
std::string pbrt_scene(const std::string& bsdf, const std::string& image);
/// The same scene for Mitsuba 3; `spectral` names the variant in its comment.
std::string mitsuba_scene(const std::string& bsdf, bool spectral);
/// Writes `text` through a temporary renamed over `path` when complete.
void write_scene(const std::filesystem::path& path, const std::string& text);

}  // namespace specula::codec
