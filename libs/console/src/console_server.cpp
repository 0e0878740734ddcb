#include "vloc/console/console_server.h"

#include <glog/logging.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <websocketpp/config/asio_no_tls.hpp>
#include <websocketpp/server.hpp>

#include "vloc/common/options.h"
#include "vloc/console/static_files.h"

namespace vloc {

using WsServer = websocketpp::server<websocketpp::config::asio>;
using Hdl = websocketpp::connection_hdl;

namespace {

using Names = std::vector<std::string>;

bool IsIpAddress(const std::string& host) {
  boost::system::error_code ec;
  boost::asio::ip::make_address(host, ec);
  return !ec;
}

bool AreHostNames(const Names& hosts) {
  for (const std::string& h : hosts)
    if (h.empty() || h.find_first_of(":/ ") != std::string::npos) return false;
  return true;
}

bool AreOrigins(const Names& origins) {
  for (const std::string& o : origins)
    if (o.rfind("http://", 0) != 0 && o.rfind("https://", 0) != 0) return false;
  return true;
}

}  // namespace

void ConsoleServerOptions::Visit(OptionsReader& r) {
  r.Optional("bind_address", &bind_address, "address to listen on (127.0.0.1: this machine only)",
             Rule<std::string>(IsIpAddress, "an IP address"));
  r.Optional("port", &port, "TCP port (0: any free port)", InRange(0, 65535));
  r.Optional("web_root", &web_root, "folder whose files are served", NonEmpty());
  r.Optional("max_client_buffer_bytes", &max_client_buffer_bytes, "bytes unsent per client before it is dropped",
             AtLeast(1024));
  r.Optional("max_message_bytes", &max_message_bytes, "bytes, largest WebSocket message accepted", AtLeast(1024));
  r.Optional("max_file_bytes", &max_file_bytes, "bytes, largest file served", AtLeast(1024));
  r.Optional("max_connections", &max_connections, "open TCP connections before requests are refused (503)", AtLeast(2));
  r.Optional("max_json_depth", &max_json_depth, "nesting of a client's JSON message", InRange(3, 256));
  r.Optional("allowed_hosts", &allowed_hosts, "Host names served besides IP addresses and localhost",
             Rule<Names>(AreHostNames, "host names (no port, no scheme)"));
  r.Optional("allowed_origins", &allowed_origins, "page origins allowed to open the WebSocket besides our own",
             Rule<Names>(AreOrigins, "origins (http[s]://host[:port])"));
  r.Optional("auth_free_failures", &auth_free_failures, "wrong tokens from one address before it is locked out",
             NonNegative());
  r.Optional("auth_max_lockout_s", &auth_max_lockout_s, "s, longest lockout after wrong tokens", InRange(1, 86400));
}

bool ConsoleServerOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::map<std::string, std::string> ParseQuery(const std::string& query) {
  std::map<std::string, std::string> out;
  std::istringstream in(query);
  std::string pair;
  while (std::getline(in, pair, '&')) {
    const size_t eq = pair.find('=');
    if (eq == std::string::npos) continue;
    std::string key, value;
    if (PercentDecode(pair.substr(0, eq), &key) && PercentDecode(pair.substr(eq + 1), &value)) out[key] = value;
  }
  return out;
}

bool JsonDepthWithin(const std::string& text, int max_depth) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return false;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return true;
}

std::string HostOfAuthority(const std::string& authority) {
  std::string host = authority;
  if (!host.empty() && host[0] == '[') {
    const size_t end = host.find(']');
    host = end == std::string::npos ? "" : host.substr(1, end - 1);
  } else if (std::count(host.begin(), host.end(), ':') == 1) {
    host = host.substr(0, host.find(':'));
  }
  std::transform(host.begin(), host.end(), host.begin(), [](unsigned char c) { return std::tolower(c); });
  return host;
}

namespace {

bool SameText(std::string a, std::string b) {
  std::transform(a.begin(), a.end(), a.begin(), [](unsigned char c) { return std::tolower(c); });
  std::transform(b.begin(), b.end(), b.begin(), [](unsigned char c) { return std::tolower(c); });
  return a == b;
}

}  // namespace

bool HostAllowed(const std::string& host_header, const std::vector<std::string>& allowed) {
  const std::string host = HostOfAuthority(host_header);
  if (host.empty()) return false;
  if (host == "localhost" || IsIpAddress(host)) return true;
  return std::any_of(allowed.begin(), allowed.end(), [&](const std::string& a) { return SameText(a, host); });
}

bool OriginAllowed(const std::string& origin, const std::string& host_header,
                   const std::vector<std::string>& allowed) {
  if (std::any_of(allowed.begin(), allowed.end(), [&](const std::string& a) { return SameText(a, origin); }))
    return true;
  const size_t scheme_end = origin.find("://");
  if (scheme_end == std::string::npos) return false;  // "null" (a file or sandboxed page) included
  const std::string scheme = origin.substr(0, scheme_end);
  if (scheme != "http" && scheme != "https") return false;
  return !host_header.empty() && SameText(origin.substr(scheme_end + 3), host_header);
}

// Wrong tokens per remote address: a few are free, then each locks the
// address out for a time doubling up to a cap. Bounded: addresses whose
// lockout has passed are forgotten first when the table is full.
class AuthThrottle {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr size_t kMaxAddresses = 4096;

  // Seconds the address is still locked out (0: it may try).
  double LockedFor(const std::string& address, Clock::time_point now) const {
    const auto it = entries_.find(address);
    if (it == entries_.end() || it->second.locked_until <= now) return 0;
    return std::chrono::duration<double>(it->second.locked_until - now).count();
  }
  void Failed(const std::string& address, Clock::time_point now, int free_failures, double max_lockout_s) {
    if (entries_.size() >= kMaxAddresses && !entries_.count(address)) Forget(now);
    Entry& e = entries_[address];
    ++e.failures;
    if (e.failures > free_failures) {
      const double lockout = std::min(max_lockout_s, std::ldexp(1.0, std::min(e.failures - free_failures - 1, 30)));
      e.locked_until = now + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(lockout));
    }
  }
  void Succeeded(const std::string& address) { entries_.erase(address); }

 private:
  struct Entry {
    int failures = 0;
    Clock::time_point locked_until{};
  };
  void Forget(Clock::time_point now) {
    for (auto it = entries_.begin(); it != entries_.end();) it = it->second.locked_until <= now ? entries_.erase(it) : ++it;
    if (entries_.size() >= kMaxAddresses) entries_.erase(entries_.begin());
  }
  std::map<std::string, Entry> entries_;
};

struct ConsoleServer::Impl {
  ConsoleServerOptions options;
  std::filesystem::path root;  // canonical web_root
  WsServer server;
  std::set<Hdl, std::owner_less<Hdl>> clients;      // open WebSockets
  std::set<Hdl, std::owner_less<Hdl>> connections;  // every open TCP connection
  CommandHandler on_command;
  ApiHandler on_api;
  WelcomeHandler on_welcome;
  ConsoleServerStats stats;
  AuthThrottle throttle;
  bool loopback = true;
  int port = 0;

  void Reply(WsServer::connection_ptr con, const HttpReply& r) {
    con->set_status(static_cast<websocketpp::http::status_code::value>(r.status));
    con->replace_header("Content-Type", r.content_type);
    con->replace_header("Cache-Control", "no-store");
    con->replace_header("X-Content-Type-Options", "nosniff");
    con->set_body(r.body);
    if (r.status >= 400) ++stats.http_rejected;
  }

  HttpReply Error(int status, const std::string& why) { return {status, "text/plain; charset=utf-8", why + "\n"}; }

  HttpReply StaticFile(const std::string& path) {
    std::filesystem::path file;
    std::string why;
    if (!ResolveStaticPath(root, path, &file, &why)) return Error(404, "not found: " + why);
    std::error_code ec;
    const auto size = std::filesystem::file_size(file, ec);
    if (ec || static_cast<int64_t>(size) > options.max_file_bytes) return Error(404, "not found: too large");
    std::ifstream in(file, std::ios::binary);
    std::string body((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return {200, ContentTypeOf(file), std::move(body)};
  }

  HttpReply Route(const std::string& method, const std::string& target) {
    if (method != "GET") return Error(405, "only GET is served");
    const size_t q = target.find('?');
    const std::string path = target.substr(0, q);
    const std::string query = q == std::string::npos ? "" : target.substr(q + 1);
    if (path.rfind("/api/", 0) == 0) {
      HttpReply r;
      if (on_api && on_api(path.substr(5), ParseQuery(query), &r)) return r;
      return Error(404, "no such API: " + path);
    }
    return StaticFile(path);
  }

  bool Crowded() {
    if (static_cast<int>(connections.size()) <= options.max_connections) return false;
    ++stats.connections_refused;
    return true;
  }

  // Whether the request's Host names this server (DNS rebinding); false and *why (counted) otherwise.
  bool OurHost(const std::string& host, std::string* why) {
    if (HostAllowed(host, options.allowed_hosts)) return true;
    ++stats.hosts_refused;
    *why = "host '" + host.substr(0, 100) + "' is not served here (server.allowed_hosts)";
    return false;
  }

  void OnHttp(Hdl hdl) {
    ++stats.http_requests;
    const WsServer::connection_ptr con = server.get_con_from_hdl(hdl);
    if (Crowded()) return Reply(con, Error(503, "busy: too many connections, try again"));
    std::string why;
    if (!OurHost(con->get_request_header("Host"), &why)) return Reply(con, Error(403, why));
    try {
      Reply(con, Route(con->get_request().get_method(), con->get_resource()));
    } catch (const std::exception& e) {
      LOG(ERROR) << "console: HTTP request " << con->get_resource() << " failed: " << e.what();
      Reply(con, Error(500, "internal error"));
    }
  }

  // The WebSocket handshake: not crowded, our Host, our page's Origin.
  bool Validate(Hdl hdl) {
    const WsServer::connection_ptr con = server.get_con_from_hdl(hdl);
    if (Crowded()) {
      con->set_status(websocketpp::http::status_code::service_unavailable);
      return false;
    }
    const std::string host = con->get_request_header("Host");
    const std::string origin = con->get_request_header("Origin");
    std::string why;
    if (OurHost(host, &why) && !origin.empty() && !OriginAllowed(origin, host, options.allowed_origins)) {
      ++stats.origins_refused;
      why = "a page from '" + origin.substr(0, 100) + "' may not open this console (server.allowed_origins)";
    }
    if (why.empty()) return true;
    LOG(WARNING) << "console: WebSocket from " << con->get_remote_endpoint() << " refused: " << why;
    con->set_status(websocketpp::http::status_code::forbidden);
    con->set_body(why + "\n");
    return false;
  }

  void Send(Hdl hdl, const std::string& text) {
    websocketpp::lib::error_code ec;
    const WsServer::connection_ptr con = server.get_con_from_hdl(hdl, ec);
    if (ec) return;
    if (static_cast<int64_t>(con->get_buffered_amount() + text.size()) > options.max_client_buffer_bytes) {
      ++stats.clients_dropped_slow;
      LOG(WARNING) << "console: client " << con->get_remote_endpoint() << " too slow (" << con->get_buffered_amount()
                   << " bytes unsent); dropped";
      clients.erase(hdl);
      con->terminate(websocketpp::lib::error_code());
      return;
    }
    server.send(hdl, text, websocketpp::frame::opcode::text, ec);
  }

  void OnOpen(Hdl hdl) {
    ++stats.clients_opened;
    clients.insert(hdl);
    if (on_welcome)
      for (const std::string& text : on_welcome()) Send(hdl, text);
  }

  void OnClose(Hdl hdl) {
    connections.erase(hdl);
    if (clients.erase(hdl)) ++stats.clients_closed;
  }

  static nlohmann::json Refusal(const std::string& why) {
    return {{"type", "reply"}, {"ok", false}, {"error", why}};
  }

  // Whether the message's token allows acting; false and *why when the
  // sender's address is locked out (its token then is not compared).
  bool Authorize(const nlohmann::json& command, const std::string& address, std::string* why) {
    const auto token_it = command.find("token");
    const std::string token =
        token_it != command.end() && token_it->is_string() ? token_it->get<std::string>() : std::string();
    if (options.token.empty() || token.empty()) return MayActWith(token);
    const auto now = AuthThrottle::Clock::now();
    if (const double locked = throttle.LockedFor(address, now); locked > 0) {
      ++stats.auth_locked_out;
      *why = "too many wrong tokens from " + address + ": try again in " + std::to_string(int(std::ceil(locked))) +
             " s";
      return false;
    }
    if (MayActWith(token)) {
      throttle.Succeeded(address);
      return true;
    }
    ++stats.auth_failures;
    throttle.Failed(address, now, options.auth_free_failures, options.auth_max_lockout_s);
    return false;
  }

  nlohmann::json Answer(const std::string& text, const std::string& address) {
    if (!JsonDepthWithin(text, options.max_json_depth)) {
      ++stats.messages_bad;
      return Refusal("JSON nested deeper than " + std::to_string(options.max_json_depth) + " levels");
    }
    nlohmann::json command = nlohmann::json::parse(text, nullptr, false);
    if (command.is_discarded() || !command.is_object()) {
      ++stats.messages_bad;
      return Refusal("not a JSON object");
    }
    std::string locked_out;
    const bool may_act = Authorize(command, address, &locked_out);
    if (!locked_out.empty()) {
      nlohmann::json reply = Refusal(locked_out);
      reply["may_act"] = false;
      if (command.contains("id")) reply["id"] = command["id"];
      return reply;
    }
    nlohmann::json reply =
        on_command ? on_command(command, may_act) : nlohmann::json{{"ok", false}, {"error", "no commands here"}};
    reply["type"] = "reply";
    if (command.contains("id")) reply["id"] = command["id"];
    return reply;
  }

  static std::string AddressOf(const WsServer::connection_ptr& con) {
    boost::system::error_code ec;
    const auto endpoint = con->get_raw_socket().remote_endpoint(ec);
    return ec ? "unknown" : endpoint.address().to_string();
  }

  void OnMessage(Hdl hdl, WsServer::message_ptr msg) {
    ++stats.messages_in;
    nlohmann::json reply;
    try {
      websocketpp::lib::error_code ec;
      const WsServer::connection_ptr con = server.get_con_from_hdl(hdl, ec);
      reply = Answer(msg->get_payload(), ec ? "unknown" : AddressOf(con));
    } catch (const std::exception& e) {
      ++stats.messages_bad;
      reply = {{"type", "reply"}, {"ok", false}, {"error", std::string("bad command: ") + e.what()}};
    }
    Send(hdl, reply.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
  }

  bool MayActWith(const std::string& token) const {
    if (options.token.empty()) return loopback;
    if (token.size() != options.token.size()) return false;
    unsigned diff = 0;  // constant time in the token's content
    for (size_t i = 0; i < token.size(); ++i) diff |= static_cast<unsigned>(token[i] ^ options.token[i]);
    return diff == 0;
  }
};

ConsoleServer::ConsoleServer(ConsoleServerOptions options) : impl_(std::make_unique<Impl>()) {
  impl_->options = std::move(options);
}

ConsoleServer::~ConsoleServer() {
  websocketpp::lib::error_code ec;
  if (impl_->server.is_listening()) impl_->server.stop_listening(ec);
}

void ConsoleServer::SetCommandHandler(CommandHandler handler) { impl_->on_command = std::move(handler); }
void ConsoleServer::SetApiHandler(ApiHandler handler) { impl_->on_api = std::move(handler); }
void ConsoleServer::SetWelcomeHandler(WelcomeHandler handler) { impl_->on_welcome = std::move(handler); }

bool ConsoleServer::Start(std::string* error) {
  Impl& m = *impl_;
  std::error_code fs_ec;
  m.root = std::filesystem::canonical(m.options.web_root, fs_ec);
  if (fs_ec || !std::filesystem::is_directory(m.root)) {
    *error = "web_root '" + m.options.web_root + "' is not a folder (run from the repository root or set web_root)";
    return false;
  }
  WsServer& s = m.server;
  s.clear_access_channels(websocketpp::log::alevel::all);
  s.clear_error_channels(websocketpp::log::elevel::all);
  websocketpp::lib::error_code ec;
  s.init_asio(ec);
  if (ec) return Fail(error, "cannot start the network layer: " + ec.message());
  s.set_reuse_addr(true);
  s.set_max_message_size(static_cast<size_t>(m.options.max_message_bytes));
  s.set_max_http_body_size(static_cast<size_t>(m.options.max_message_bytes));
  s.set_tcp_pre_init_handler([&m](Hdl h) { m.connections.insert(h); });
  s.set_validate_handler([&m](Hdl h) { return m.Validate(h); });
  s.set_http_handler([&m](Hdl h) { m.OnHttp(h); });
  s.set_open_handler([&m](Hdl h) { m.OnOpen(h); });
  s.set_close_handler([&m](Hdl h) { m.OnClose(h); });
  s.set_fail_handler([&m](Hdl h) { m.OnClose(h); });
  s.set_message_handler([&m](Hdl h, WsServer::message_ptr msg) { m.OnMessage(h, msg); });
  const auto address = boost::asio::ip::make_address(m.options.bind_address);
  m.loopback = address.is_loopback();
  s.listen(boost::asio::ip::tcp::endpoint(address, static_cast<unsigned short>(m.options.port)), ec);
  if (ec)
    return Fail(error, "cannot listen on " + m.options.bind_address + ":" + std::to_string(m.options.port) + ": " +
                           ec.message() + " (choose another port or bind_address)");
  s.start_accept(ec);
  if (ec) return Fail(error, "cannot accept connections: " + ec.message());
  boost::system::error_code asio_ec;
  m.port = s.get_local_endpoint(asio_ec).port();
  if (!m.loopback && m.options.token.empty())
    LOG(WARNING) << "console: listening on " << m.options.bind_address
                 << " without a token: other machines can watch, nobody can act (set token to allow it)";
  return true;
}

int ConsoleServer::port() const { return impl_->port; }

size_t ConsoleServer::Poll() {
  try {
    return impl_->server.poll();
  } catch (const std::exception& e) {
    LOG(ERROR) << "console: server handler failed: " << e.what() << "; continuing";
    return 1;
  }
}

void ConsoleServer::Broadcast(const std::string& text) {
  ++impl_->stats.broadcasts;
  const auto clients = impl_->clients;  // Send may drop a slow one
  for (const Hdl& hdl : clients) impl_->Send(hdl, text);
}

int ConsoleServer::num_clients() const { return static_cast<int>(impl_->clients.size()); }
const ConsoleServerStats& ConsoleServer::stats() const { return impl_->stats; }
bool ConsoleServer::MayAct(const std::string& token) const { return impl_->MayActWith(token); }

}  // namespace vloc
