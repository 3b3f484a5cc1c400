#include "specula/store/io/gdal.h"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <mutex>
#include <optional>
#include <regex>

#include "specula/core/error.h"
#include "specula/core/text.h"

namespace specula::store {
namespace {

// GDAL's block cache, capped unless the user set GDAL_CACHEMAX: strips are read once, so a cache of 5 % of the RAM
// (GDAL's default) would only hold memory the import is meant not to use.
constexpr long long kCacheBytes = 64ll << 20;

void init_gdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    if (!CPLGetConfigOption("GDAL_CACHEMAX", nullptr)) GDALSetCacheMax64(kCacheBytes);
  });
}

// GDAL reports errors through a per-thread handler; this keeps them off stderr and hands back the last message.
class QuietErrors {
 public:
  QuietErrors() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietErrors() { CPLPopErrorHandler(); }
  QuietErrors(const QuietErrors&) = delete;
  QuietErrors& operator=(const QuietErrors&) = delete;
  static std::string message() {
    std::string m = CPLGetLastErrorMsg();
    for (char& c : m)
      if (c == '\n' || c == '\r') c = ' ';
    return m.empty() ? std::string("no message") : m;
  }
};

GDALDatasetH ds(void* p) { return static_cast<GDALDatasetH>(p); }

// A metadata item of a band in the default, ENVI or IMAGERY domain (any case of the key), or empty.
std::string band_item(GDALRasterBandH band, std::initializer_list<const char*> keys) {
  for (const char* domain : {"", "ENVI", "IMAGERY"})
    for (const char* key : keys) {
      const char* v = GDALGetMetadataItem(band, key, domain);
      if (!v) {
        const std::string up = [&] {
          std::string s = key;
          for (char& c : s) c = char(std::toupper(static_cast<unsigned char>(c)));
          return s;
        }();
        v = GDALGetMetadataItem(band, up.c_str(), domain);
      }
      if (v && *v) return v;
    }
  return {};
}

std::optional<double> number(const std::string& s) {
  const char* b = s.c_str();
  char* e = nullptr;
  const double v = std::strtod(b, &e);
  if (e == b || !std::isfinite(v)) return std::nullopt;
  return v;
}

// nm per unit of a wavelength_units text; nullopt when unknown.
std::optional<double> unit_scale(std::string u) {
  u = lower(u);
  if (u.empty()) return std::nullopt;
  if (u.find("nano") != std::string::npos || u == "nm") return 1.0;
  if (u.find("micro") != std::string::npos || u == "um" || u == "µm" || u == "microns") return 1000.0;
  if (u.find("milli") != std::string::npos || u == "mm") return 1e6;
  return std::nullopt;
}

// Values without stated units: micrometres when all lie in [0.2, 20] and not all are integers (as store/io/mat.h).
void to_nm(std::vector<double>& v) {
  const bool in_um = std::all_of(v.begin(), v.end(), [](double x) { return x >= 0.2 && x <= 20; }) &&
                     !std::all_of(v.begin(), v.end(), [](double x) { return x == std::round(x); });
  if (in_um)
    for (double& x : v) x *= 1000;
}

// "{ 450, 460 }" or "450,460" as numbers.
std::vector<double> number_list(const std::string& s) {
  std::vector<double> out;
  std::string cur;
  for (char c : s + ",") {
    if (c == ',' || c == '{' || c == '}') {
      if (auto v = number(cur)) out.push_back(*v);
      cur.clear();
    } else {
      cur += c;
    }
  }
  return out;
}

// A band's centre wavelength and FWHM from its metadata (wavelength + wavelength_units, CENTRAL_WAVELENGTH_UM,
// fwhm, FWHM_UM) or a description ending in a wavelength with its unit; nm says the wavelength's unit was known.
struct BandWavelength {
  std::optional<double> w, fwhm;
  bool nm = false;
};

BandWavelength band_wavelength(GDALRasterBandH band) {
  static const std::regex in_description(
      R"(([0-9]+(\.[0-9]*)?)\s*(nm|nanometers?|um|µm|micrometers?|microns?)\s*\)?\s*$)", std::regex::icase);
  BandWavelength out;
  auto& w = out.w;
  bool& nm_given = out.nm;
  const std::string units = band_item(band, {"wavelength_units"});
  if (const std::string v = band_item(band, {"wavelength"}); !v.empty()) {
    if ((w = number(v))) {
      if (auto s = unit_scale(units)) *w *= *s, nm_given = true;
    }
  } else if (const std::string um = band_item(band, {"CENTRAL_WAVELENGTH_UM"}); !um.empty()) {
    if ((w = number(um))) *w *= 1000, nm_given = true;
  } else if (const char* desc = GDALGetDescription(band); desc && *desc) {
    std::cmatch m;
    if (std::regex_search(desc, m, in_description)) {
      w = std::strtod(m[1].str().c_str(), nullptr);
      if (lower(m[3].str()).find('n') == std::string::npos) *w *= 1000;
      nm_given = true;
    }
  }
  auto& f = out.fwhm;
  if (const std::string v = band_item(band, {"fwhm"}); !v.empty()) {
    if ((f = number(v)))
      if (auto s = unit_scale(units)) *f *= *s;
  } else if (const std::string um = band_item(band, {"FWHM_UM"}); !um.empty()) {
    if ((f = number(um))) *f *= 1000;
  }
  return out;
}

}  // namespace

std::uint64_t gdal_strip_bytes(std::size_t width, std::size_t bands, std::size_t rows) {
  return std::uint64_t(rows) * width * (bands * sizeof(float) + 1);
}

GdalRaster::GdalRaster(const std::filesystem::path& path, const WavelengthGrid& fallback) : file_(path.string()) {
  init_gdal();
  QuietErrors quiet;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(file_ + ": no such file; give the path of a raster GDAL reads (GeoTIFF, ...)");
  dataset_ = GDALOpenEx(file_.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr);
  if (!dataset_) throw InputError(file_ + ": not a raster GDAL can read (GDAL: " + QuietErrors::message() + ")");
  try {
    GDALDatasetH d = ds(dataset_);
    driver_ = GDALGetDriverShortName(GDALGetDatasetDriver(d));
    const int nb = GDALGetRasterCount(d);
    height_ = std::size_t(GDALGetRasterYSize(d));
    width_ = std::size_t(GDALGetRasterXSize(d));
    if (nb <= 0 || height_ == 0 || width_ == 0)
      throw InputError(file_ + ": the " + driver_ + " raster holds no bands or no pixels");
    std::vector<double> wl, fwhm;
    bool wl_all = true, fwhm_all = true, nm_given = false;
    for (int b = 1; b <= nb; ++b) {
      GDALRasterBandH band = GDALGetRasterBand(d, b);
      const GDALDataType t = GDALGetRasterDataType(band);
      if (GDALDataTypeIsComplex(t))
        throw InputError(file_ + ": band " + std::to_string(b) + " is complex (" + GDALGetDataTypeName(t) +
                         "); store its real part or magnitude as a real raster");
      int has = 0;
      const double nd = GDALGetRasterNoDataValue(band, &has);
      nodata_.push_back(nd);
      has_nodata_.push_back(has != 0);
      int has_scale = 0, has_offset = 0;
      const double sc = GDALGetRasterScale(band, &has_scale), of = GDALGetRasterOffset(band, &has_offset);
      scale_.push_back(has_scale ? sc : 1.0);
      offset_.push_back(has_offset ? of : 0.0);
      if ((has_scale && sc != 1.0) || (has_offset && of != 0.0)) scaled_ = true;
      if (b == 1) {
        const int flags = GDALGetMaskFlags(band);
        dataset_mask_ = (flags & GMF_PER_DATASET) && !(flags & GMF_ALL_VALID) && !(flags & GMF_NODATA);
      }

      const BandWavelength bw = band_wavelength(band);
      nm_given = nm_given || bw.nm;
      if (bw.w)
        wl.push_back(*bw.w);
      else
        wl_all = false;
      if (bw.fwhm)
        fwhm.push_back(*bw.fwhm);
      else
        fwhm_all = false;
    }
    if (!wl_all) {  // the dataset's ENVI domain: wavelength = { ... }
      wl =
          number_list(GDALGetMetadataItem(d, "wavelength", "ENVI") ? GDALGetMetadataItem(d, "wavelength", "ENVI") : "");
      const char* u = GDALGetMetadataItem(d, "wavelength_units", "ENVI");
      nm_given = false;
      if (wl.size() == std::size_t(nb) && u)
        if (auto s = unit_scale(u)) {
          for (double& x : wl) x *= *s;
          nm_given = true;
        }
      wl_all = wl.size() == std::size_t(nb);
    }
    if (wl_all) {
      if (!nm_given) to_nm(wl);
      wavelengths_ = WavelengthGrid(wl, file_ + ": band wavelengths");
      if (fwhm_all) fwhm_ = fwhm;
    } else if (!fallback.empty()) {
      if (fallback.size() != std::size_t(nb))
        throw InputError(file_ + ": the `wavelengths` option gives " + std::to_string(fallback.size()) +
                         " wavelengths for " + std::to_string(nb) + " bands; give one per band");
      wavelengths_ = fallback;
    } else {
      throw InputError(file_ + ": the " + driver_ + " raster's " + std::to_string(nb) +
                       " bands carry no wavelengths in their metadata; give the `wavelengths` option "
                       "FIRST:LAST:STEP (one per band)");
    }
  } catch (...) {
    GDALClose(ds(dataset_));
    throw;
  }
}

GdalRaster::~GdalRaster() {
  if (dataset_) GDALClose(ds(dataset_));
}

void GdalRaster::read_rows(std::size_t y0, std::size_t rows, std::span<float> spectra, std::span<std::uint8_t> mask) {
  const std::size_t nb = bands(), px = rows * width_;
  if (rows == 0 || y0 + rows > height_ || spectra.size() != px * nb || mask.size() != px)
    throw UsageError(file_ + ": read_rows range or buffer sizes are wrong");
  QuietErrors quiet;
  GDALDatasetH d = ds(dataset_);
  const GSpacing pixel = GSpacing(nb * sizeof(float)), line = GSpacing(width_) * pixel;
  if (GDALDatasetRasterIOEx(d, GF_Read, 0, int(y0), int(width_), int(rows), spectra.data(), int(width_), int(rows),
                            GDT_Float32, int(nb), nullptr, pixel, line, sizeof(float), nullptr) != CE_None)
    throw InputError(file_ + ": cannot read rows " + std::to_string(y0) + " to " + std::to_string(y0 + rows - 1) +
                     " (GDAL: " + QuietErrors::message() + "); the file may be truncated or corrupt");
  std::fill(mask.begin(), mask.end(), std::uint8_t{1});
  if (dataset_mask_) {
    GDALRasterBandH m = GDALGetMaskBand(GDALGetRasterBand(d, 1));
    if (GDALRasterIO(m, GF_Read, 0, int(y0), int(width_), int(rows), mask.data(), int(width_), int(rows), GDT_Byte, 0,
                     0) != CE_None)
      throw InputError(file_ + ": cannot read the mask band at rows " + std::to_string(y0) + " to " +
                       std::to_string(y0 + rows - 1) + " (GDAL: " + QuietErrors::message() + ")");
    for (auto& v : mask) v = v != 0;
  }
  for (std::size_t b = 0; b < nb; ++b) {
    if (!has_nodata_[b]) continue;
    const float nd = static_cast<float>(nodata_[b]);
    const bool nan = std::isnan(nodata_[b]);
    for (std::size_t p = 0; p < px; ++p) {
      const float v = spectra[p * nb + b];
      if (nan ? std::isnan(v) : v == nd) mask[p] = 0;
    }
  }
  if (scaled_)
    for (std::size_t p = 0; p < px; ++p)
      for (std::size_t b = 0; b < nb; ++b)
        spectra[p * nb + b] = static_cast<float>(spectra[p * nb + b] * scale_[b] + offset_[b]);
}

}  // namespace specula::store
