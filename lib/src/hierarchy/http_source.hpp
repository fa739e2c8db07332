// A cache read from a web server by HTTP range requests (issue 45, item 2):
// any static server that answers `Range: bytes=A-B` with 206 and the bytes
// asked for (nginx, Apache, S3, python's servers that speak ranges). Paged
// drawing reads its meta part and then its pages one request each, as
// Potree's viewer and COPC readers fetch their hierarchy and nodes.
//
// Nothing a server says is trusted: a reply without 206, a Content-Range
// other than the range asked for, a body of another length, a total that
// changed since the file was opened, a server that stalls or fails, each
// is one line naming the URL ("URL: reading bytes 0-99: the server ignored
// the range (HTTP 200)") and, for the pages, their checksums do the rest.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "../import/byte_source.hpp"

namespace treecut::detail {

/// Whether WHERE names a URL this reader takes (http:// or https://).
bool is_http_url(std::string_view where);

struct HttpOptions {
  /// A read that receives nothing for this long fails (a stalled server).
  int stall_ms = 15000;
  int connect_timeout_ms = 10000;
  /// Tries of one read when the server fails (5xx) or the transfer breaks.
  int attempts = 2;
};

class HttpSource final : public ByteSource {
 public:
  /// Asks URL for its first byte to learn its size and that it answers
  /// ranges. Throws InputError "URL: reason".
  HttpSource(std::string url, const HttpOptions& options);
  ~HttpSource() override;
  HttpSource(const HttpSource&) = delete;
  HttpSource& operator=(const HttpSource&) = delete;

  [[nodiscard]] std::uint64_t size() const override { return size_; }
  /// Any thread (each read takes a connection of its own from a pool).
  /// InputError, or FileChangedError when the file changed on the server.
  void read(std::uint64_t at, void* out, std::size_t n) const override;

 private:
  struct Connections;
  // One range request of N bytes at AT into OUT, checked; the size the
  // server gave in its Content-Range is stored in *TOTAL.
  void fetch(std::uint64_t at, void* out, std::size_t n, std::uint64_t* total) const;

  std::string url_, name_;
  HttpOptions options_;
  std::uint64_t size_ = 0;
  std::unique_ptr<Connections> connections_;
};

}  // namespace treecut::detail
