// specula view: serves a local web page for looking at a store (images as sRGB under an illuminant, the spectrum
// under the mouse with its reconstruction from a basis, single bands; BRDF grids as spheres and incidence-plane
// plots; scattered samples as incidence-plane scatter). The API is apps/view/service.h; this file only binds it to
// cpp-httplib. Loopback unless --host is given.
#include <fmt/format.h>

#include <csignal>
#include <memory>

#include "apps/commands.h"
#include "apps/view/service.h"
#include "specula/core/error.h"

// After Eigen: httplib pulls in <resolv.h>, whose _res macro breaks Eigen headers included after it.
#include <httplib.h>

namespace specula::app {
namespace {

struct ViewOptions {
  std::string store;
  std::string host = "127.0.0.1";
  int port = 8080;
};

httplib::Server* running = nullptr;

extern "C" void stop_server(int) {
  if (running) running->stop();
}

void run_view(const ViewOptions& o) {
  if (o.port < 0 || o.port > 65535) throw UsageError("view: --port must be 0 to 65535 (0 picks a free port)");
  view::Service service(store::Store::open(o.store));
  httplib::Server server;
  server.Get(".*", [&](const httplib::Request& req, httplib::Response& res) {
    view::Query q;
    for (const auto& [k, v] : req.params) q[k] = v;
    const view::Response r = service.get(req.path, q);
    res.status = r.status;
    res.set_header("Cache-Control", "no-store");
    res.set_content(r.body, r.content_type.c_str());
  });
  const int port = o.port == 0 ? server.bind_to_any_port(o.host.c_str())
                               : (server.bind_to_port(o.host.c_str(), o.port) ? o.port : -1);
  if (port < 0)
    throw InputError(fmt::format(
        "view: cannot listen on {}:{} (in use, or not an address of this machine); try --port 0", o.host, o.port));
  fmt::print("serving {} at http://{}:{}/ (Ctrl-C stops)\n", o.store, o.host, port);
  std::fflush(stdout);
  running = &server;
  std::signal(SIGINT, stop_server);
  std::signal(SIGTERM, stop_server);
  server.listen_after_bind();
  running = nullptr;
}

}  // namespace

void setup_view(CLI::App& app) {
  auto o = std::make_shared<ViewOptions>();
  auto* cmd = app.add_subcommand("view", "Serve an interactive spectral viewer of a store on a local web page");
  cmd->add_option("store", o->store, "Store (.h5)")->required();
  cmd->add_option("--port", o->port, "TCP port (0: any free port, printed)");
  cmd->add_option("--host", o->host, "Address to listen on; other than 127.0.0.1 exposes the store to the network");
  cmd->callback([o] { run_view(*o); });
}

}  // namespace specula::app
