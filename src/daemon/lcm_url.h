#pragma once

#include <string>

namespace clutterseg::daemon {

/// Checks the syntax of an LCM URL before LCM sees it. liblcm 1.3.1 runs with a warning on
/// some malformed URLs (udpm://...?ttl=abc, unknown options, port 0, a unicast address) and
/// reports others as a missing multicast route; this names the actual mistake instead.
///
/// Accepted: "" (LCM's default), udpm://[ADDR[:PORT]][?ttl=0..255&recv_buf_size=N&
/// transmit_only=true|false] with ADDR an IPv4 multicast address (224.0.0.0 .. 239.255.255.255)
/// and PORT 1..65535; mpudpm://...; memq://; file:///abs/path?mode=w|a[&speed=..]
/// (the daemon writes logs); tcpq://[HOST[:PORT]].
/// @return an empty string when the URL is acceptable, otherwise what is wrong and how to fix
/// it (one line). Thread-safety: pure function.
std::string CheckLcmUrl(const std::string& url);

/// LCM's own default URL when none is configured.
inline constexpr char kLcmDefaultUrl[] = "udpm://239.255.76.67:7667?ttl=0";

/// The URL to open: `configured` when it is non-empty, else $LCM_DEFAULT_URL (the variable
/// every LCM program honours), else kLcmDefaultUrl. Thread-safety: reads the environment.
std::string ResolveLcmUrl(const std::string& configured);

}  // namespace clutterseg::daemon
