#include "specula/codec/rgl_scene.h"

#include <cerrno>
#include <cstring>
#include <fstream>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"

namespace specula::codec {

std::string pbrt_scene(const std::string& bsdf, const std::string& image) {
  return "# pbrt-v4 scene written by specula: the RGL material " + bsdf +
         " on a sphere.\n"
         "# Render: pbrt this.pbrt (pbrt-v4 reads spectral .bsdf files only).\n"
         "LookAt 0 0 4.5  0 0 0  0 1 0\n"
         "Camera \"perspective\" \"float fov\" [ 30 ]\n"
         "Sampler \"zsobol\" \"integer pixelsamples\" [ 256 ]\n"
         "Film \"rgb\" \"string filename\" [ \"" +
         image +
         "\" ] \"integer xresolution\" [ 512 ] \"integer yresolution\" [ 512 ]\n"
         "WorldBegin\n"
         "LightSource \"infinite\" \"rgb L\" [ 0.45 0.5 0.6 ]\n"
         "LightSource \"distant\" \"point3 from\" [ 2 3 4 ] \"point3 to\" [ 0 0 0 ] \"blackbody L\" [ 5500 ] \"float "
         "scale\" [ 2.5 ]\n"
         "AttributeBegin\n"
         "  Material \"measured\" \"string filename\" [ \"" +
         bsdf +
         "\" ]\n"
         "  Shape \"sphere\" \"float radius\" [ 1 ]\n"
         "AttributeEnd\n";
}

std::string mitsuba_scene(const std::string& bsdf, bool spectral) {
  return std::string("<?xml version=\"1.0\"?>\n") + "<!-- Mitsuba 3 scene written by specula: the RGL material " +
         bsdf +
         " on a sphere.\n"
         "     Render: mitsuba -m " +
         (spectral ? "scalar_spectral" : "scalar_rgb") + " this.xml (" +
         (spectral ? "spectral files need a spectral variant" : "RGB files need an RGB variant") +
         ") -->\n"
         "<scene version=\"3.0.0\">\n"
         "  <integrator type=\"path\"/>\n"
         "  <sensor type=\"perspective\">\n"
         "    <float name=\"fov\" value=\"30\"/>\n"
         "    <transform name=\"to_world\"><lookat origin=\"0, 0, 4.5\" target=\"0, 0, 0\" up=\"0, 1, "
         "0\"/></transform>\n"
         "    <sampler type=\"independent\"><integer name=\"sample_count\" value=\"256\"/></sampler>\n"
         "    <film type=\"hdrfilm\"><integer name=\"width\" value=\"512\"/><integer name=\"height\" "
         "value=\"512\"/></film>\n"
         "  </sensor>\n"
         "  <emitter type=\"constant\"><rgb name=\"radiance\" value=\"0.45, 0.5, 0.6\"/></emitter>\n"
         "  <emitter type=\"directional\">\n"
         "    <vector name=\"direction\" value=\"-2, -3, -4\"/>\n"
         "    <rgb name=\"irradiance\" value=\"2.5, 2.5, 2.5\"/>\n"
         "  </emitter>\n"
         "  <shape type=\"sphere\">\n"
         "    <float name=\"radius\" value=\"1\"/>\n"
         "    <bsdf type=\"measured\"><string name=\"filename\" value=\"" +
         bsdf +
         "\"/></bsdf>\n"
         "  </shape>\n"
         "</scene>\n";
}

void write_scene(const std::filesystem::path& path, const std::string& text) {
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path(), std::ios::binary | std::ios::trunc);
    f << text;
    f.flush();
    if (!f) throw LibraryError(path.string() + ": write failed (" + std::strerror(errno) + ")");
  }
  out.commit();
}

}  // namespace specula::codec
