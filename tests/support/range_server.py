#!/usr/bin/env python3
"""A static web server for treecut's tests of caches by URL (issue 45).

Serves the files of ROOT on 127.0.0.1 (a free port, printed on the first
line) with HTTP range requests, and the faults a server may have, chosen
by the path's first part:

  /ok/NAME                 ranges as asked (206, Content-Range)
  /slow/NAME               the same, each reply 0.2 s late
  /no-ranges/NAME          the whole file (200) whatever the Range says
  /fail/NAME               500 for everything
  /fail-from/OFFSET/NAME   500 for ranges that start at OFFSET or later
                           (but the last 8 bytes: a cache's checksum)
  /stall-from/OFFSET/NAME  those ranges' headers, then nothing (30 s)
  /shifted/NAME            206 and the Content-Range asked, the bytes one further
  /wrong-range/NAME        206 with a Content-Range one byte further than asked

Python's http.server itself ignores Range, hence this one.
"""
import http.server
import os
import re
import socketserver
import sys
import time

ROOT = sys.argv[1]


class Handler(http.server.BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"

    def log_message(self, *args):
        pass

    def reply(self, code, body=b"", headers=None):
        self.send_response(code)
        for key, value in (headers or {}).items():
            self.send_header(key, value)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        try:
            self.wfile.write(body)
        except OSError:  # the client hung up (a reader that refused the reply)
            pass

    def do_GET(self):
        parts = self.path.strip("/").split("/")
        mode, threshold = parts[0], None
        if mode in ("fail-from", "stall-from"):
            threshold, parts = int(parts[1]), parts[2:]
        else:
            parts = parts[1:]
        try:
            with open(os.path.join(ROOT, *parts), "rb") as f:
                data = f.read()
        except OSError:
            return self.reply(404)
        if mode == "fail":
            return self.reply(500)
        if mode == "slow":
            time.sleep(0.2)
        asked = re.match(r"bytes=(\d+)-(\d+)$", self.headers.get("Range", ""))
        if mode == "no-ranges" or not asked:
            return self.reply(200, data)
        first, last = int(asked.group(1)), int(asked.group(2))
        if first >= len(data):
            return self.reply(416, b"", {"Content-Range": "bytes */%d" % len(data)})
        last = min(last, len(data) - 1)
        said = "bytes %d-%d/%d" % (first, last, len(data))
        # (The file's last 8 bytes, the checksum read when it opens, excepted.)
        if threshold is not None and first >= threshold and last < len(data) - 8:
            if mode == "fail-from":
                return self.reply(500)
            self.send_response(206)
            self.send_header("Content-Range", said)
            self.send_header("Content-Length", str(last - first + 1))
            self.end_headers()
            self.wfile.flush()
            time.sleep(30)
            return None
        body = data[first:last + 1]
        if mode == "shifted":
            body = data[first + 1:last + 2].ljust(last - first + 1, b"\0")
        if mode == "wrong-range":
            said = "bytes %d-%d/%d" % (first + 1, last + 1, len(data))
        return self.reply(206, body, {"Content-Range": said})


class Server(socketserver.ThreadingMixIn, http.server.HTTPServer):
    daemon_threads = True


if __name__ == "__main__":
    server = Server(("127.0.0.1", 0), Handler)
    print(server.server_address[1], flush=True)
    server.serve_forever()
