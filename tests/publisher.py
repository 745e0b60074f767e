"""A publisher for `dataset fetch` tests: a folder served over a loopback HTTP server (no
network in CI), in a thread, where chosen files misbehave as real servers do."""

from __future__ import annotations

import functools
import http.server
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

#: a trickling server sends one byte per beat
BEAT_S = 0.05


@contextmanager
def serve(folder: Path, slow: dict[str, str] | None = None) -> Iterator[tuple[str, list[str]]]:
    """Serve ``folder`` on 127.0.0.1 (a free port); yields its URL and the paths requested.
    ``slow`` maps a path to how it misbehaves: "trickle" (one byte per beat, forever), "silent"
    (four bytes, then nothing), "missing" (404)."""
    requested: list[str] = []
    slow = slow or {}
    done = threading.Event()

    class Handler(http.server.SimpleHTTPRequestHandler):
        def do_GET(self):
            requested.append(self.path)
            how = slow.get(self.path.lstrip("/"))
            if how is None:
                return super().do_GET()
            if how == "missing":
                return self.send_error(404)
            self.send_response(200)
            self.send_header("Content-Length", "100000")
            self.end_headers()
            try:
                self.wfile.write(b"t,g1")
                self.wfile.flush()
                while how == "trickle" and not done.wait(BEAT_S):
                    self.wfile.write(b"0")
                    self.wfile.flush()
                done.wait()
            except OSError:  # the client gave up
                pass

        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(Handler, directory=str(folder))
    )
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}", requested
    finally:
        done.set()
        server.shutdown()
        server.server_close()
