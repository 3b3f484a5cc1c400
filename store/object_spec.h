#pragma once
// The one way an object in a store is named on a command line or in a file: STORE.h5:NAME.
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace specula::store {

/// A store's path and the name of an object in it.
struct ObjectSpec {
  std::filesystem::path file;
  std::string name;  ///< may be empty ("a.h5:"), for validate_name() to refuse with its message
};

/// `spec` split at its last colon into the store's path and the object's name; nullopt when it has no colon or nothing
/// before it. Whether the path is a store (exists, ends in .h5) is the caller's question.
std::optional<ObjectSpec> parse_object_spec(std::string_view spec);

}  // namespace specula::store
