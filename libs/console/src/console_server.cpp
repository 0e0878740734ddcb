#include "vloc/console/console_server.h"

#include <glog/logging.h>

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

void ConsoleServerOptions::Visit(OptionsReader& r) {
  r.Optional("bind_address", &bind_address, "address to listen on (127.0.0.1: this machine only)");
  r.Optional("port", &port, "TCP port (0: any free port)");
  r.Optional("web_root", &web_root, "folder whose files are served");
  r.Optional("max_client_buffer_bytes", &max_client_buffer_bytes, "bytes unsent per client before it is dropped");
  r.Optional("max_message_bytes", &max_message_bytes, "bytes, largest WebSocket message accepted");
  r.Optional("max_file_bytes", &max_file_bytes, "bytes, largest file served");
  r.Optional("max_connections", &max_connections, "open TCP connections before requests are refused (503)");
}

bool ConsoleServerOptions::Check(std::string* error) const {
  boost::system::error_code ec;
  boost::asio::ip::make_address(bind_address, ec);
  if (ec) return Fail(error, "bind_address '" + bind_address + "' is not an IP address");
  if (port < 0 || port > 65535) return Fail(error, "port must be in [0, 65535]");
  if (web_root.empty()) return Fail(error, "web_root must name the console's web folder");
  if (max_client_buffer_bytes < 1024 || max_message_bytes < 1024 || max_file_bytes < 1024)
    return Fail(error, "max_client_buffer_bytes, max_message_bytes and max_file_bytes must be >= 1024");
  if (max_connections < 2) return Fail(error, "max_connections must be >= 2");
  return true;
}

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

  void OnHttp(Hdl hdl) {
    ++stats.http_requests;
    const WsServer::connection_ptr con = server.get_con_from_hdl(hdl);
    if (Crowded()) return Reply(con, Error(503, "busy: too many connections, try again"));
    try {
      Reply(con, Route(con->get_request().get_method(), con->get_resource()));
    } catch (const std::exception& e) {
      LOG(ERROR) << "console: HTTP request " << con->get_resource() << " failed: " << e.what();
      Reply(con, Error(500, "internal error"));
    }
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

  nlohmann::json Answer(const std::string& text) {
    nlohmann::json command = nlohmann::json::parse(text, nullptr, false);
    if (command.is_discarded() || !command.is_object()) {
      ++stats.messages_bad;
      return {{"type", "reply"}, {"ok", false}, {"error", "not a JSON object"}};
    }
    const nlohmann::json token = command.value("token", nlohmann::json());
    const bool may_act = MayActWith(token.is_string() ? token.get<std::string>() : std::string());
    nlohmann::json reply =
        on_command ? on_command(command, may_act) : nlohmann::json{{"ok", false}, {"error", "no commands here"}};
    reply["type"] = "reply";
    if (command.contains("id")) reply["id"] = command["id"];
    return reply;
  }

  void OnMessage(Hdl hdl, WsServer::message_ptr msg) {
    ++stats.messages_in;
    nlohmann::json reply;
    try {
      reply = Answer(msg->get_payload());
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
  s.set_validate_handler([&m](Hdl) { return !m.Crowded(); });
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
