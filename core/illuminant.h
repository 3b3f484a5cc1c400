#pragma once
// Illuminants named as users write them: a CIE name, a daylight CCT, a black body, or an SPD file.
#include <Eigen/Core>
#include <string_view>

#include "specula/core/wavelengths.h"

namespace specula {

/// Whether an illuminant spec may name a file (a command line may; a web page or other remote caller may not).
enum class IlluminantFiles { allowed, refused };

/// The SPD named by `spec` at `grid`: "D65", "D50", "A", "E", "D<CCT/100>" daylight (D75 = 7500 K),
/// "blackbody:K" (500-50000 K) or, when files are allowed, a CSV file of "wavelength_nm,value" rows (header
/// optional, ';' accepted) resampled to the grid. Throws UsageError naming the spec and the forms it may take,
/// InputError naming the file and line for a malformed SPD file.
Eigen::VectorXd parse_illuminant(std::string_view spec, const WavelengthGrid& grid,
                                 IlluminantFiles files = IlluminantFiles::allowed);

}  // namespace specula
