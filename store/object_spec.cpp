#include "specula/store/object_spec.h"

namespace specula::store {

std::optional<ObjectSpec> parse_object_spec(std::string_view spec) {
  const auto colon = spec.rfind(':');
  if (colon == std::string_view::npos || colon == 0) return std::nullopt;
  return ObjectSpec{std::filesystem::path(spec.substr(0, colon)), std::string(spec.substr(colon + 1))};
}

}  // namespace specula::store
