#include "clutterseg/daemon/lcm_url.h"

#include <cstdint>
#include <cstdlib>
#include <initializer_list>
#include <string_view>
#include <vector>

namespace clutterseg::daemon {
namespace {

// Parses a decimal integer that fills all of `s`.
bool ParseInt(std::string_view s, int64_t* value) {
  if (s.empty() || s.size() > 18) return false;
  int64_t v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + (c - '0');
  }
  *value = v;
  return true;
}

// Dotted IPv4 address; returns the first octet in `*first`.
bool ParseIpv4(std::string_view s, int* first) {
  int parts = 0;
  size_t start = 0;
  for (;;) {
    const size_t dot = s.find('.', start);
    const std::string_view part =
        s.substr(start, dot == std::string_view::npos ? std::string_view::npos : dot - start);
    int64_t v = 0;
    if (part.size() > 3 || !ParseInt(part, &v) || v > 255) return false;
    if (parts == 0) *first = static_cast<int>(v);
    ++parts;
    if (dot == std::string_view::npos) break;
    start = dot + 1;
  }
  return parts == 4;
}

// Concatenates the parts (operator+ chains on string_view conversions trip a false GCC 12
// -Wrestrict warning at -O3).
std::string Cat(std::initializer_list<std::string_view> parts) {
  std::string out;
  for (std::string_view p : parts) out.append(p);
  return out;
}

struct Option {
  std::string_view key;
  std::string_view value;
};

std::vector<Option> SplitOptions(std::string_view query) {
  std::vector<Option> out;
  size_t start = 0;
  while (start <= query.size() && !query.empty()) {
    const size_t amp = query.find('&', start);
    const std::string_view kv =
        query.substr(start, amp == std::string_view::npos ? std::string_view::npos : amp - start);
    const size_t eq = kv.find('=');
    out.push_back(
        {kv.substr(0, eq), eq == std::string_view::npos ? std::string_view() : kv.substr(eq + 1)});
    if (amp == std::string_view::npos) break;
    start = amp + 1;
  }
  return out;
}

std::string CheckUdpm(std::string_view rest) {
  const size_t q = rest.find('?');
  const std::string_view target = rest.substr(0, q);
  const std::string_view query = q == std::string_view::npos ? "" : rest.substr(q + 1);
  if (!target.empty()) {
    const size_t colon = target.find(':');
    const std::string_view addr = target.substr(0, colon);
    int first = 0;
    if (!ParseIpv4(addr, &first)) {
      return Cat({"'", addr, "' is not an IPv4 address (e.g. udpm://239.255.76.67:7667)"});
    }
    if (first < 224 || first > 239) {
      return Cat({"'", addr,
                  "' is not a multicast address: udpm needs one in 224.0.0.0 .. 239.255.255.255 ",
                  "(e.g. 239.255.76.67)"});
    }
    if (colon != std::string_view::npos) {
      const std::string_view port = target.substr(colon + 1);
      int64_t p = 0;
      if (!ParseInt(port, &p) || p < 1 || p > 65535) {
        return Cat({"port '", port, "' is not in 1..65535 (e.g. 7667)"});
      }
    }
  }
  for (const Option& o : SplitOptions(query)) {
    int64_t v = 0;
    if (o.key == "ttl") {
      if (!ParseInt(o.value, &v) || v > 255) {
        return Cat({"ttl=", o.value, " is not 0..255 (ttl=0 keeps the traffic on this host)"});
      }
    } else if (o.key == "recv_buf_size") {
      if (!ParseInt(o.value, &v) || v < 1) {
        return Cat({"recv_buf_size=", o.value, " is not a positive number of bytes"});
      }
    } else if (o.key == "transmit_only") {
      if (o.value != "true" && o.value != "false") {
        return Cat({"transmit_only=", o.value, " is not true or false"});
      }
    } else {
      return Cat({"unknown udpm option '", o.key, "' (known: ttl, recv_buf_size, transmit_only)"});
    }
  }
  return "";
}

std::string CheckFile(std::string_view rest) {
  const size_t q = rest.find('?');
  const std::string_view path = rest.substr(0, q);
  const std::string_view query = q == std::string_view::npos ? "" : rest.substr(q + 1);
  if (path.empty() || path.front() != '/') {
    return "file:// needs an absolute path: file:///abs/path/out.lcmlog?mode=w";
  }
  bool writes = false;
  for (const Option& o : SplitOptions(query)) {
    if (o.key == "mode") {
      if (o.value != "w" && o.value != "a") {
        return Cat(
            {"mode=", o.value, " cannot be published to: use mode=w (new log) or mode=a (append)"});
      }
      writes = true;
    } else if (o.key != "speed" && o.key != "start_timestamp") {
      return Cat({"unknown file option '", o.key, "' (known: mode, speed, start_timestamp)"});
    }
  }
  if (!writes) return "file:// opens logs for reading by default: add ?mode=w to write one";
  return "";
}

}  // namespace

std::string CheckLcmUrl(const std::string& url) {
  if (url.empty()) return "";
  const size_t sep = url.find("://");
  if (sep == std::string::npos) {
    return "'" + url +
           "' is not a URL: expected PROVIDER://..., e.g. udpm://239.255.76.67:7667?ttl=0";
  }
  const std::string scheme = url.substr(0, sep);
  const std::string_view rest = std::string_view(url).substr(sep + 3);
  std::string why;
  if (scheme == "udpm" || scheme == "mpudpm") {
    why = scheme == "udpm" ? CheckUdpm(rest) : "";
  } else if (scheme == "file") {
    why = CheckFile(rest);
  } else if (scheme == "memq" || scheme == "tcpq") {
    why = "";
  } else {
    why = "unknown LCM provider '" + scheme + "' (known: udpm, mpudpm, memq, file, tcpq)";
  }
  return why;
}

std::string ResolveLcmUrl(const std::string& configured) {
  if (!configured.empty()) return configured;
  const char* env = std::getenv("LCM_DEFAULT_URL");
  if (env != nullptr && env[0] != '\0') return env;
  return kLcmDefaultUrl;
}

}  // namespace clutterseg::daemon
