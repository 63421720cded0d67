#include "stampscan/hmi/tls_front.hpp"

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/hmi/auth.hpp"

#include <algorithm>
#include <sstream>
#include <stdexcept>

namespace stampscan::hmi {

namespace {

void check(const TlsFront& f) {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("the panel's TLS front: " + what); };
  if (f.server_names.empty()) fail("no server name: list the names the panel is reached under ([hmi] server_names)");
  for (const std::string& name : f.server_names)
    if (!acquisition::isServerName(name))
      fail("'" + name + "' is not a host name or an IPv4 address");
  for (const auto& [what, path] : {std::pair{"certificate", f.certificate}, std::pair{"key", f.key}}) {
    if (path.empty() || path.front() != '/') fail(std::string("the ") + what + " needs an absolute path, not '" + path + "'");
    if (!acquisition::isQuotablePath(path))
      fail(std::string("the ") + what + "'s path '" + path + "' holds quotes, '$', ';', braces, '\\' or a control character");
  }
  // An address literal: nginx would try every address a name resolves to, the panel listens on one.
  const auto colon = f.upstream.rfind(':');
  if (colon == std::string::npos || !isLoopbackHost(f.upstream.substr(0, colon)) || f.upstream.rfind("localhost", 0) == 0 ||
      f.upstream.find_first_not_of("0123456789", colon + 1) != std::string::npos || colon + 1 == f.upstream.size())
    fail("the panel behind the front listens on a loopback HOST:PORT, not '" + f.upstream + "'");
  if (f.https_port < 1 || f.https_port > 65535 || f.http_port < 1 || f.http_port > 65535 || f.https_port == f.http_port)
    fail("the HTTPS and HTTP ports must be two ports 1-65535");
}

// Text for a comment line: printable ASCII only (a line break would end the comment).
std::string commentText(const std::string& text) {
  std::string out = text;
  for (char& ch : out)
    if (ch < 0x20 || ch > 0x7e) ch = '?';
  return out;
}

}  // namespace

std::string nginxSite(const TlsFront& f) {
  check(f);
  // The names nginx holds for the whole http block carry the port: two panels' fronts can share it.
  const std::string id = "stampscan_" + std::to_string(f.https_port);
  std::string names;
  for (const std::string& n : f.server_names) names += " " + n;
  const std::string https = std::to_string(f.https_port), http = std::to_string(f.http_port);
  const std::string to_https = f.https_port == 443 ? "https://$host$request_uri" : "https://$host:" + https + "$request_uri";
  const std::string body_kib = std::to_string((f.body_limit_bytes + 1023) / 1024) + "k";
  std::ostringstream o;
  // What a client may take of the front before it names the panel: the same short times as the
  // panel's own server, so that a name it is not served under holds nothing for long either.
  const std::string client_limits = "    client_header_timeout 10s;\n    keepalive_timeout 30s;\n"
                                    "    large_client_header_buffers 4 8k;\n";
  o << "# The operator's panel of the cell '" << commentText(f.cell_name) << "' behind nginx: TLS, plain HTTP\n"
    << "# redirected, HSTS, and limits on what one client may send or hold. Written by `station hmi\n"
    << "# --front-config` from the cell file's [hmi] section; it goes into nginx's http block (for example\n"
    << "# as /etc/nginx/sites-enabled/stampscan-panel, with Debian's sites-enabled/default removed: this\n"
    << "# file's catch-all servers are the ports' defaults). Check it with `nginx -t`, then reload nginx.\n"
    << "\n"
    << "limit_conn_zone $binary_remote_addr zone=" << id << "_connections:1m;\n"
    << "limit_req_zone $binary_remote_addr zone=" << id << "_logins:1m rate=10r/m;\n"
    << "\n"
    << "# The panel closes an idle connection after 5 s: nginx lets its own go before that.\n"
    << "upstream " << id << "_panel {\n"
    << "    server " << f.upstream << ";\n"
    << "    keepalive 8;\n"
    << "    keepalive_timeout 4s;\n"
    << "}\n"
    << "\n"
    << "# A name the panel is not served under: refused.\n"
    << "server {\n"
    << "    listen " << https << " ssl http2 default_server;\n"
    << "    server_name _;\n"
    << "    ssl_certificate \"" << f.certificate << "\";\n"
    << "    ssl_certificate_key \"" << f.key << "\";\n"
    << client_limits
    << "    return 421;\n"
    << "}\n"
    << "server {\n"
    << "    listen " << http << " default_server;\n"
    << "    server_name _;\n"
    << client_limits
    << "    return 444;\n"
    << "}\n"
    << "\n"
    << "# Plain HTTP: redirected to HTTPS.\n"
    << "server {\n"
    << "    listen " << http << ";\n"
    << "    server_name" << names << ";\n"
    << client_limits
    << "    return 301 " << to_https << ";\n"
    << "}\n"
    << "\n"
    << "server {\n"
    << "    listen " << https << " ssl http2;\n"
    << "    server_name" << names << ";\n"
    << "    ssl_certificate \"" << f.certificate << "\";\n"
    << "    ssl_certificate_key \"" << f.key << "\";\n"
    << "    ssl_protocols TLSv1.2 TLSv1.3;\n"
    << "    ssl_session_cache shared:" << id << "_tls:1m;\n"
    << "    ssl_session_timeout 1h;\n"
    << "    add_header Strict-Transport-Security \"max-age=31536000\" always;\n"
    << "    add_header X-Content-Type-Options nosniff always;\n"
    << "    add_header X-Frame-Options DENY always;\n"
    << "\n"
    << "    # What one client may send or hold. The body limit counts chunked bodies as they come.\n"
    << "    client_max_body_size " << body_kib << ";\n"
    << "    client_body_buffer_size " << body_kib << ";\n"
    << "    client_header_timeout 10s;\n"
    << "    client_body_timeout 10s;\n"
    << "    send_timeout 30s;\n"
    << "    keepalive_timeout 30s;\n"
    << "    large_client_header_buffers 4 8k;\n"
    << "    limit_conn " << id << "_connections 32;\n"
    << "    limit_conn_status 429;\n"
    << "\n"
    << "    # The panel gets whole bodies with their length (it refuses chunked ones), the client's name\n"
    << "    # and port as it asked (the panel checks them, and the Origin against them), and who it is.\n"
    << "    proxy_http_version 1.1;\n"
    << "    proxy_request_buffering on;\n"
    << "    proxy_set_header Connection \"\";\n"
    << "    proxy_set_header Host $http_host;\n"
    << "    proxy_set_header X-Forwarded-For $remote_addr;\n"
    << "    proxy_set_header X-Forwarded-Proto https;\n"
    << "    proxy_connect_timeout 5s;\n"
    << "    proxy_read_timeout 300s;\n"
    << "\n"
    << "    # Login attempts per client (the panel locks a name after repeated wrong passwords).\n"
    << "    location = /api/login {\n"
    << "        limit_req zone=" << id << "_logins burst=5 nodelay;\n"
    << "        limit_req_status 429;\n"
    << "        proxy_pass http://" << id << "_panel;\n"
    << "    }\n"
    << "    # The live events (Server-Sent Events): passed on as they come and held open; the panel sends\n"
    << "    # a keep-alive every 10 s.\n"
    << "    location = /api/events {\n"
    << "        proxy_buffering off;\n"
    << "        proxy_read_timeout 1h;\n"
    << "        proxy_pass http://" << id << "_panel;\n"
    << "    }\n"
    << "    location / {\n"
    << "        proxy_pass http://" << id << "_panel;\n"
    << "    }\n"
    << "}\n";
  return o.str();
}

}  // namespace stampscan::hmi
