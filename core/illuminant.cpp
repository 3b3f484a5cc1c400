#include "specula/core/illuminant.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "specula/core/cie.h"
#include "specula/core/error.h"

namespace specula {
namespace {

bool parse_double(const std::string& s, double& v) {
  try {
    std::size_t pos = 0;
    v = std::stod(s, &pos);
    return pos == s.size();
  } catch (...) {
    return false;
  }
}

Eigen::VectorXd read_spd_file(const std::string& path, const WavelengthGrid& grid) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot be read as an SPD file");
  std::vector<double> nm, val;
  std::string line;
  std::size_t lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    std::replace(line.begin(), line.end(), ';', ',');
    const auto comma = line.find(',');
    double a = 0, b = 0;
    if (comma == std::string::npos || !parse_double(line.substr(0, comma), a) ||
        !parse_double(line.substr(comma + 1), b)) {
      if (nm.empty()) continue;  // header
      throw InputError(path + ":" + std::to_string(lineno) + ": expected 'wavelength_nm,value'");
    }
    if (!std::isfinite(b)) throw InputError(path + ":" + std::to_string(lineno) + ": value is not finite");
    nm.push_back(a);
    val.push_back(b);
  }
  if (nm.size() < 2) throw InputError(path + ": an SPD needs at least two 'wavelength_nm,value' rows");
  const WavelengthGrid src(nm, path);
  return resample_matrix(src, grid, path) * Eigen::Map<const Eigen::VectorXd>(val.data(), Eigen::Index(val.size()));
}

}  // namespace

Eigen::VectorXd parse_illuminant(std::string_view spec_view, const WavelengthGrid& grid, IlluminantFiles files) {
  const std::string spec(spec_view);
  if (spec == "D65" || spec == "D50" || spec == "A" || spec == "E") return illuminant(spec, grid);
  double v = 0;
  if (spec.size() > 1 && (spec[0] == 'D' || spec[0] == 'd') && parse_double(spec.substr(1), v)) {
    if (!(v >= 40 && v <= 250))
      throw UsageError("illuminant '" + spec + "': daylight is D<CCT/100> between D40 and D250 (e.g. D75 = 7500 K)");
    return daylight(v * 100.0, grid);
  }
  if (spec.rfind("blackbody:", 0) == 0 && parse_double(spec.substr(10), v)) {
    if (!(v >= 500 && v <= 50000)) throw UsageError("illuminant '" + spec + "': temperature must be 500-50000 K");
    return blackbody(v, grid);
  }
  const std::string forms = "D65, D50, A, E, D<CCT/100> (e.g. D75) or blackbody:<K>";
  if (files == IlluminantFiles::refused) throw UsageError("illuminant '" + spec + "': use " + forms);
  if (!std::filesystem::is_regular_file(spec))
    throw UsageError("illuminant '" + spec + "' is neither " + forms + " nor an existing SPD file");
  return read_spd_file(spec, grid);
}

}  // namespace specula
