#pragma once
// The HTTP API behind `specula view`, independent of the server library: a GET request (path and query
// parameters) becomes a response (status, content type, body). Every answer is computed from one store opened
// read-only; nothing outside it is ever read, and names are checked against the store's own lists before use.
// Endpoints and their parameters: docs/viewer.md.
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "specula/store/store.h"

namespace specula::view {

/// One HTTP answer.
struct Response {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
};

using Query = std::map<std::string, std::string>;

/// The viewer's data service over one store. Thread-safe: requests are served one at a time.
class Service {
 public:
  /// Opens nothing itself; `store` stays open for the service's life.
  explicit Service(store::Store store);

  /// Answers GET `path` with `query`: 200 with the data, 400 naming a malformed parameter, 404 for an unknown
  /// path or object, 500 with the library's message when the store cannot be read.
  Response get(const std::string& path, const Query& query);

 private:
  Response dispatch(const std::string& path, const Query& query);
  Response store_listing();
  Response image_rgb(const Query& q);
  Response image_band(const Query& q);
  Response image_spectrum(const Query& q);
  Response grid_sphere(const Query& q);
  Response grid_incidence(const Query& q);
  Response samples_incidence(const Query& q);
  const store::Cube& image(const std::string& name);
  const store::Grid& grid(const std::string& name);
  const store::Grid& confidence(const std::string& name);

  store::Store store_;
  std::mutex mutex_;
  // The last image and grid read (one of each: memory is bounded by the largest single object, never the store).
  std::string image_name_, grid_name_;
  std::unique_ptr<store::Cube> image_;
  std::unique_ptr<store::Grid> grid_;
  std::string confidence_name_;  // and the last confidence grid beside a grid (one band)
  std::unique_ptr<store::Grid> confidence_;
  std::map<std::string, std::string> png_cache_;  // a few recent renders, keyed by request
};

/// The page's files compiled into the binary: path ("/", "/viewer.js", ...) to (content type, bytes).
std::optional<std::pair<std::string, std::string>> asset(const std::string& path);

}  // namespace specula::view
