#include "cli/dash_server.hpp"

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <cstdio>

#include "dash_assets.hpp"

namespace noisemon::cli {
namespace {

// One browser's event stream: what it has been sent, and when.
struct Client {
  std::uint64_t sent = 0;
  std::uint64_t checks = 0;  // check tables it has seen
  bool first = true;
  std::chrono::steady_clock::time_point last_send{};
};

// Writes the next piece of a client's stream; false ends it (shutdown or the browser went away).
bool next_event(DashState& state, Client& c, std::chrono::milliseconds min_interval, httplib::DataSink& sink) {
  if (c.first) {  // the reconnection delay, then the whole history at once
    c.first = false;
    c.last_send = std::chrono::steady_clock::now();
    c.checks = state.checks();
    const std::string data = "retry: 1000\ndata: " + state.event_json(0, c.sent) + "\n\n";
    return sink.write(data.data(), data.size());
  }
  std::this_thread::sleep_until(c.last_send + min_interval);  // the throttle: late cycles go into the next event
  const std::uint64_t seq = state.wait_newer(c.sent, std::chrono::seconds(2), c.checks);
  if (state.stopped()) return false;
  const std::uint64_t checks = state.checks();
  // A comment line every 2 s without cycles or a check: finds browsers that went away.
  const bool idle = seq == c.sent && checks == c.checks;
  c.checks = checks;
  const std::string data = idle ? std::string(": idle\n\n") : "data: " + state.event_json(c.sent, c.sent) + "\n\n";
  c.last_send = std::chrono::steady_clock::now();
  return sink.write(data.data(), data.size());
}

}  // namespace

DashServer::DashServer(DashState& state, std::chrono::milliseconds min_interval, RecordControl record_control)
    : state_(state),
      min_interval_(min_interval),
      record_control_(std::move(record_control)),
      server_(std::make_unique<httplib::Server>()) {
  // Each event stream holds a thread: room for many browsers beside the plain requests.
  server_->new_task_queue = [] { return new httplib::ThreadPool(32); };
  routes();
}

DashServer::~DashServer() { stop(); }

void DashServer::routes() {
  for (const auto& asset : dash_assets::kAssets) {
    server_->Get(asset.url, [&asset](const httplib::Request&, httplib::Response& res) {
      res.set_header("Cache-Control", "no-cache");
      res.set_content(reinterpret_cast<const char*>(asset.data), asset.size, asset.content_type);
    });
  }
  server_->Get("/api/state", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    res.set_content(state_.state_json(), "application/json");
  });
  server_->Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
    res.set_content(state_.metrics_text(), "text/plain; version=0.0.4; charset=utf-8");
  });
  if (record_control_)
    server_->Post("/api/record", [this](const httplib::Request& req, httplib::Response& res) {
      const nlohmann::json body = nlohmann::json::parse(req.body, nullptr, false);
      ControlAnswer a{400, nlohmann::json{{"error", "expected {\"action\": ..., \"argument\": ...}"}}.dump()};
      if (body.is_object() && body.value("action", nlohmann::json()).is_string())
        a = record_control_(body["action"].get<std::string>(), body.value("argument", std::string()));
      res.status = a.status;
      res.set_header("Cache-Control", "no-store");
      res.set_content(a.json, "application/json");
    });
  server_->Get("/events", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    auto client = std::make_shared<Client>();
    res.set_chunked_content_provider("text/event-stream", [this, client](std::size_t, httplib::DataSink& sink) {
      if (next_event(state_, *client, min_interval_, sink)) return true;
      sink.done();
      return false;
    });
  });
}

bool DashServer::start(const std::string& host, int port) {
  port_ = port == 0 ? server_->bind_to_any_port(host) : (server_->bind_to_port(host, port) ? port : -1);
  if (port_ <= 0) {
    std::fprintf(stderr, "noisemon dash: cannot listen on %s:%d\n", host.c_str(), port);
    return false;
  }
  thread_ = std::thread([this] { server_->listen_after_bind(); });
  return true;
}

void DashServer::stop() {
  if (!thread_.joinable()) return;
  server_->stop();
  thread_.join();
}

}  // namespace noisemon::cli
