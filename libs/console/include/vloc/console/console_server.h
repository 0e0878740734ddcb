#pragma once
// The web console's server: HTTP (the web folder's files and an API hook)
// and WebSocket (JSON text both ways) on one port, single-threaded: Poll()
// runs whatever is ready and returns, so a process's LCM loop calls it
// between waits. No LCM here (layer 2).
//
// Safety: only files inside web_root are served (static_files.h); a
// client whose unsent data exceeds max_client_buffer_bytes is dropped (a
// slow client never grows the process); malformed HTTP or WebSocket input
// closes that one connection; beyond max_connections open TCP connections
// a request gets 503 (idle sockets end after websocketpp's 5 s handshake
// timeout); a WebSocket message that is not a JSON object, or nests deeper
// than max_json_depth, gets an error reply without being parsed into a tree.
//
// A web page on another site must neither read nor act (DNS rebinding,
// cross-site WebSockets): every request's Host must be an IP address,
// "localhost" or one of allowed_hosts (403 otherwise), and a WebSocket
// whose Origin is not the console's own (same host and port as the Host
// header) or one of allowed_origins is refused at the handshake (403). A
// client without Origin is not a browser and is not a page's puppet.
// "Acting" (decided by the command handler) is allowed when the message's
// "token" matches the configured one; with no token configured, only when
// bound to a loopback address (where the origin check makes the page the
// console's own). Wrong tokens are rate-limited per remote address: after
// auth_free_failures, every further one locks that address out for a time
// doubling from 1 s to auth_max_lockout_s, during which no token it sends
// is even compared.

#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace vloc {

class OptionsReader;

struct ConsoleServerOptions {
  std::string bind_address = "127.0.0.1";           // IPv4 or IPv6 address to listen on (0.0.0.0: every interface)
  int port = 8765;                                  // TCP port (0: any free port, printed at start)
  std::string web_root = "procs/vloc_console/web";  // folder whose files are served (relative: to the working dir)
  std::string token;  // required by acting commands when set ("" = act only on loopback); not a config key (it
                      // would be echoed in the log): $VLOC_CONSOLE_TOKEN or --token
  int64_t max_client_buffer_bytes = 8 << 20;        // bytes, unsent data per client before it is dropped as too slow
  int64_t max_message_bytes = 1 << 20;              // bytes, largest WebSocket message accepted from a browser
  int64_t max_file_bytes = 16 << 20;                // bytes, largest file served
  int max_connections = 64;                         // open TCP connections; beyond, requests get 503 / are refused
  int max_json_depth = 16;                          // nesting of a client's JSON message (commands need 3)
  std::vector<std::string> allowed_hosts;           // Host names served besides IP addresses and localhost
  std::vector<std::string> allowed_origins;         // page origins (scheme://host:port) allowed besides our own
  int auth_free_failures = 3;                       // wrong tokens from one address before it is locked out
  double auth_max_lockout_s = 60;                   // s, longest lockout (doubles from 1 s per wrong token)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct HttpReply {
  int status = 200;
  std::string content_type = "application/octet-stream";
  std::string body;
};

struct ConsoleServerStats {
  int64_t http_requests = 0, http_rejected = 0;  // requests, of which refused (4xx)
  int64_t clients_opened = 0, clients_closed = 0, clients_dropped_slow = 0;
  int64_t connections_refused = 0;                  // over max_connections
  int64_t messages_in = 0, messages_bad = 0, broadcasts = 0;
  int64_t hosts_refused = 0, origins_refused = 0;  // requests / handshakes refused by the Host / Origin checks
  int64_t auth_failures = 0, auth_locked_out = 0;   // wrong tokens compared; tokens not compared (locked out)
};

class ConsoleServer {
 public:
  // Answers one JSON command; `may_act` says whether its token allows acting.
  using CommandHandler = std::function<nlohmann::json(const nlohmann::json& command, bool may_act)>;
  // Answers GET /api/<rest>; false = 404.
  using ApiHandler =
      std::function<bool(const std::string& rest, const std::map<std::string, std::string>& query, HttpReply* reply)>;
  // Messages a newly opened client is sent first (the current picture).
  using WelcomeHandler = std::function<std::vector<std::string>()>;

  explicit ConsoleServer(ConsoleServerOptions options);
  ~ConsoleServer();
  ConsoleServer(const ConsoleServer&) = delete;
  ConsoleServer& operator=(const ConsoleServer&) = delete;

  void SetCommandHandler(CommandHandler handler);
  void SetApiHandler(ApiHandler handler);
  void SetWelcomeHandler(WelcomeHandler handler);

  // Binds and listens; false and one line in *error when it cannot.
  bool Start(std::string* error);
  int port() const;  // the bound port (after Start)
  // Runs every ready handler without waiting; returns how many ran.
  size_t Poll();
  // Sends `text` to every open WebSocket client (slow ones are dropped).
  void Broadcast(const std::string& text);
  int num_clients() const;
  const ConsoleServerStats& stats() const;
  bool MayAct(const std::string& token) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// "a=1&b=x" -> {a: 1, b: x} (values percent-decoded; malformed pairs skipped).
std::map<std::string, std::string> ParseQuery(const std::string& query);

// Whether JSON text nests arrays / objects at most `max_depth` deep
// (brackets inside strings do not count); linear, no tree built.
bool JsonDepthWithin(const std::string& text, int max_depth);

// The host of a Host header value or of an origin's authority
// ("Example.org:80" -> "example.org", "[::1]:8765" -> "::1"), lower-cased.
std::string HostOfAuthority(const std::string& authority);
// Whether a request's Host header names this server: an IP address,
// "localhost", or one of `allowed` (case-insensitive; a port is ignored).
bool HostAllowed(const std::string& host_header, const std::vector<std::string>& allowed);
// Whether a browser's Origin may open a WebSocket: the page came from this
// server (its authority equals the Host header) or is listed in `allowed`.
bool OriginAllowed(const std::string& origin, const std::string& host_header,
                   const std::vector<std::string>& allowed);

}  // namespace vloc
