// The panel's TLS front on the plant's network: Debian's nginx before `station hmi`. nginx holds
// what a panel served by a thread per connection cannot: TLS, plain HTTP redirected, HSTS, a body
// limit for every transfer encoding, read times for the request's head and body, connections per
// client, login attempts per client (the panel itself locks a name after repeated wrong passwords),
// and any number of slow or idle connections without a thread each. The panel behind it listens on
// loopback and every user logs in (hmi_server.hpp).
//
// nginxSite writes the front's site file (it goes into nginx's http block, e.g.
// /etc/nginx/sites-enabled/stampscan-panel) from the cell file's [hmi] section; `station hmi
// --front-config` prints it.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace stampscan::hmi {

struct TlsFront {
  std::string cell_name;                   // named in the file's heading
  std::string upstream = "127.0.0.1:8080";  // the panel's HOST:PORT, a loopback address
  std::vector<std::string> server_names;   // the names the front serves the panel under
  std::string certificate, key;            // PEM files, absolute paths
  int https_port = 443, http_port = 80;
  std::size_t body_limit_bytes = 1 << 20;  // the panel's own limit of a request's body
};

// The site file. Throws std::invalid_argument naming what is missing or not allowed (no names, a
// relative path, a character that would break out of the file's quoting, an upstream that is not
// a loopback HOST:PORT).
std::string nginxSite(const TlsFront& front);

}  // namespace stampscan::hmi
