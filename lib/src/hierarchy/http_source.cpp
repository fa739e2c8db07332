// HttpSource: a cache's bytes by HTTP range requests through libcurl
// (http_source.hpp has the promises). One easy handle a read, taken from a
// pool so that the I/O threads reuse their connections.
#include "http_source.hpp"

#include <curl/curl.h>

#include <algorithm>
#include <cctype>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <utility>
#include <vector>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut::detail {

namespace {

// A failed read: what to say, and whether another try may do better.
struct Failed {
  std::string reason;
  bool transient = false;
  bool changed = false;  // the file changed on the server
};

// Where a reply's body goes: exactly the bytes asked for, no more.
struct Body {
  unsigned char* out;
  std::size_t size;
  std::size_t got = 0;
  bool overflow = false;
};

std::size_t on_body(char* data, std::size_t one, std::size_t n, void* user) {
  Body& b = *static_cast<Body*>(user);
  const std::size_t len = one * n;
  if (len > b.size - b.got) {
    b.overflow = true;
    return 0;  // aborts the transfer (CURLE_WRITE_ERROR)
  }
  std::memcpy(b.out + b.got, data, len);
  b.got += len;
  return len;
}

// The Content-Range of a reply ("bytes A-B/TOTAL"); the last one wins (a
// redirect's first reply has its own headers).
struct Headers {
  bool has_range = false;
  std::uint64_t first = 0, last = 0, total = 0;
};

std::size_t on_header(char* data, std::size_t one, std::size_t n, void* user) {
  Headers& h = *static_cast<Headers*>(user);
  const std::size_t len = one * n;
  const std::string line(data, len);
  constexpr std::string_view kName = "content-range:";
  if (line.size() > kName.size()) {
    std::string lower = line.substr(0, kName.size());
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (lower == kName) {
      std::uint64_t a = 0, b = 0, t = 0;
      h.has_range = std::sscanf(line.c_str() + kName.size(),
                                " bytes %" SCNu64 "-%" SCNu64 "/%" SCNu64, &a, &b, &t) == 3;
      h.first = a, h.last = b, h.total = t;
    }
  }
  return len;
}

// libcurl's global state, made before the first request (thread-safe
// since 7.84) and released at exit, so leak checkers see none of it.
void curl_ready() {
  static const struct Global {
    Global() { curl_global_init(CURL_GLOBAL_DEFAULT); }
    ~Global() { curl_global_cleanup(); }
  } global;
}

}  // namespace

bool is_http_url(std::string_view where) {
  return where.starts_with("http://") || where.starts_with("https://");
}

struct HttpSource::Connections {
  std::mutex mutex;
  std::vector<CURL*> idle;
  ~Connections() {
    for (CURL* c : idle) curl_easy_cleanup(c);
  }
  CURL* take() {
    {
      std::lock_guard lock(mutex);
      if (!idle.empty()) {
        CURL* c = idle.back();
        idle.pop_back();
        return c;
      }
    }
    CURL* c = curl_easy_init();
    if (c == nullptr) throw std::runtime_error("libcurl: no easy handle");
    return c;
  }
  void give(CURL* c) {
    std::lock_guard lock(mutex);
    idle.push_back(c);
  }
};

HttpSource::HttpSource(std::string url, const HttpOptions& options)
    : url_(std::move(url)),
      name_(quoted_name(url_)),
      options_(options),
      connections_(std::make_unique<Connections>()) {
  curl_ready();
  unsigned char first = 0;
  std::uint64_t total = 0;
  for (int attempt = 1;; ++attempt) {
    try {
      fetch(0, &first, 1, &total);
      break;
    } catch (const Failed& f) {
      if (f.transient && attempt < options_.attempts) continue;
      throw InputError(name_ + ": " + f.reason);
    }
  }
  size_ = total;
}

HttpSource::~HttpSource() = default;

void HttpSource::read(std::uint64_t at, void* out, std::size_t n) const {
  if (n == 0) return;
  for (int attempt = 1;; ++attempt) {
    try {
      std::uint64_t total = 0;
      fetch(at, out, n, &total);
      if (total != size_) {
        throw Failed{"changed on the server (" + std::to_string(total) + " bytes, " +
                         std::to_string(size_) + " when opened)",
                     false, true};
      }
      return;
    } catch (const Failed& f) {
      if (f.transient && attempt < options_.attempts) continue;
      if (f.changed) throw FileChangedError(name_ + ": " + f.reason);
      throw InputError(name_ + ": " + f.reason);
    }
  }
}

void HttpSource::fetch(std::uint64_t at, void* out, std::size_t n, std::uint64_t* total) const {
  const std::uint64_t last = at + n - 1;
  const std::string range = std::to_string(at) + "-" + std::to_string(last);
  const std::string what = "reading bytes " + range + ": ";
  CURL* c = connections_->take();
  struct Give {  // the handle back to the pool, whatever happens
    Connections* pool;
    CURL* c;
    ~Give() {
      curl_easy_reset(c);
      pool->give(c);
    }
  } give{connections_.get(), c};
  Body body{static_cast<unsigned char*>(out), n};
  Headers headers;
  char error[CURL_ERROR_SIZE] = {};
  curl_easy_setopt(c, CURLOPT_URL, url_.c_str());
  curl_easy_setopt(c, CURLOPT_RANGE, range.c_str());
  curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, &on_body);
  curl_easy_setopt(c, CURLOPT_WRITEDATA, &body);
  curl_easy_setopt(c, CURLOPT_HEADERFUNCTION, &on_header);
  curl_easy_setopt(c, CURLOPT_HEADERDATA, &headers);
  curl_easy_setopt(c, CURLOPT_ERRORBUFFER, error);
  curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c, CURLOPT_FOLLOWLOCATION, 1L);
  curl_easy_setopt(c, CURLOPT_MAXREDIRS, 5L);
  curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT_MS, static_cast<long>(options_.connect_timeout_ms));
  // A stall: under a byte a second for stall_ms (whole seconds, at least 1).
  curl_easy_setopt(c, CURLOPT_LOW_SPEED_LIMIT, 1L);
  curl_easy_setopt(c, CURLOPT_LOW_SPEED_TIME,
                   static_cast<long>(std::max(1, (options_.stall_ms + 999) / 1000)));
  // No compression: a range is of the file's bytes, not of an encoding.
  curl_easy_setopt(c, CURLOPT_HTTP_CONTENT_DECODING, 0L);
  const CURLcode rc = curl_easy_perform(c);
  long status = 0;
  curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &status);
  if (status == 200)
    throw Failed{what + "the server ignored the range (HTTP 200): it cannot serve pages"};
  if (body.overflow)
    throw Failed{what + "the server sent more than the " + std::to_string(n) + " bytes asked for"};
  // A stall already waited stall_ms: not tried again (a frame never waits
  // for it, but the page's group would wait twice as long).
  if (rc == CURLE_OPERATION_TIMEDOUT)
    throw Failed{what + "nothing received for " +
                 std::to_string(std::max(1, (options_.stall_ms + 999) / 1000)) +
                 " s (the server stalled)"};
  if (rc != CURLE_OK) {
    const std::string text = error[0] != '\0' ? error : curl_easy_strerror(rc);
    throw Failed{what + text, true};
  }
  if (status == 416) throw Failed{what + "past the end (HTTP 416)", false, true};
  if (status != 206) throw Failed{what + "HTTP " + std::to_string(status), status >= 500};
  if (!headers.has_range)
    throw Failed{what + "the reply names no Content-Range (HTTP 206 without one)"};
  if (headers.first != at || headers.last != last)
    throw Failed{what + "the server answered bytes " + std::to_string(headers.first) + "-" +
                 std::to_string(headers.last)};
  if (body.got != n)
    throw Failed{what + "the server sent " + std::to_string(body.got) + " of " + std::to_string(n) +
                     " bytes",
                 true};
  *total = headers.total;
}

}  // namespace treecut::detail
