#!/usr/bin/env python3
"""scripts/ros2_sources.py, as on a machine without ../shared/ros2-src/: the sources are
downloaded from their repositories' archives, checked against ros2-sources.lock, and packed
as the tests expect; a changed archive, a changed tarball or no network stop with one line
naming what is wrong. The repositories are played by an HTTP server on 127.0.0.1 serving
archives laid out as GitHub's (`REPO-COMMIT/` prefix, the whole tree: the lock's
include/exclude must cut them down), made from the shipped tarballs plus files the lock
leaves out. Needs ../shared/ros2-src/ (or $TRACER_ROS2_SRC) for those tarballs.

    python3 tests/ros2_sources_test.py
"""

import hashlib
import http.server
import io
import os
import subprocess
import sys
import tarfile
import tempfile
import threading
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "ros2_sources.py"
sys.path.insert(0, str(SCRIPT.parent))
import ros2_sources  # noqa: E402  (its files' digest, the one the lock holds)
LOCK = tomllib.loads((ROOT / "ros2-sources.lock").read_text())
SHIPPED = Path(os.environ.get("TRACER_ROS2_SRC") or ROOT.parent / "shared" / "ros2-src")
# Three sources with every feature of the lock: include (mcap), exclude (yaml-cpp), two
# parts under prefixes (rmw_zenoh).
NAMES = ["mcap", "yaml-cpp", "rmw_zenoh"]
# Files a repository has that the shipped tarball left out, per source.
EXTRA = {"mcap": ["typescript/core/index.ts", "go/mcap/writer.go"], "yaml-cpp": ["test/node_test.cpp"]}


def github_archives(name):
    """{url path: archive bytes} for the parts of a source, as GitHub would serve them."""
    source = LOCK[name]
    with tarfile.open(SHIPPED / f"{name}.tar.gz") as shipped:
        members = [(m, shipped.extractfile(m).read() if m.isfile() else None) for m in shipped.getmembers()]
    out = {}
    for part in source["parts"]:
        repo, commit = part["repository"], part["commit"]
        top = f"{repo.split('/')[1]}-{commit}"
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w:gz") as tar:
            for m, data in members:
                rel = m.name.split("/", 1)[1] if "/" in m.name else ""
                prefix = part.get("prefix")
                if prefix:
                    if not (rel == prefix or rel.startswith(prefix + "/")):
                        continue
                    rel = rel[len(prefix) + 1 :]
                if not rel or not (m.isfile() or m.issym()):
                    continue
                info = tarfile.TarInfo(f"{top}/{rel}")
                info.mode, info.mtime = m.mode, 1700000000
                if m.issym():
                    info.type, info.linkname = tarfile.SYMTYPE, m.linkname
                    tar.addfile(info)
                else:
                    info.size = len(data)
                    tar.addfile(info, io.BytesIO(data))
            for rel in EXTRA.get(name, []):
                data = b"left out by the lock\n"
                info = tarfile.TarInfo(f"{top}/{rel}")
                info.size = len(data)
                tar.addfile(info, io.BytesIO(data))
        out[f"/{repo}/archive/{commit}.tar.gz"] = buf.getvalue()
    return out


class Server:
    """The archives over HTTP on 127.0.0.1, on a free port."""

    def __init__(self, archives):
        files = archives

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self):
                body = files.get(self.path)
                self.send_response(200 if body else 404)
                self.end_headers()
                self.wfile.write(body or b"not found")

            def log_message(self, *a):
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()


def run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True)


def sha256(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def tree_of(path):
    return ros2_sources.tarball_tree(path)


def one_line_error(r, *words):
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1, (r.returncode, r.stderr)
    assert all(w in lines[0] for w in words), (lines[0], words)
    return lines[0]


def main():
    missing = [n for n in NAMES if not (SHIPPED / f"{n}.tar.gz").is_file()]
    if missing:
        print(f"ros2_sources_test: skipped: no {', '.join(missing)} in {SHIPPED}")
        return 0
    archives = {}
    for name in NAMES:
        archives.update(github_archives(name))
    server = Server(archives)
    with tempfile.TemporaryDirectory() as tmp:
        empty, cache = Path(tmp, "empty"), Path(tmp, "cache")
        empty.mkdir()
        base = ["--search", str(empty), "--cache", str(cache), "--url", server.url]

        # 1. Downloaded, cut to the lock's paths, checked and packed: the same files as the
        #    shipped tarball, the same bytes on a second download.
        r = run(*base, "path", *NAMES)
        assert r.returncode == 0, r.stderr
        paths = r.stdout.split()
        assert paths == [str(cache / f"{n}.tar.gz") for n in NAMES], paths
        for name, path in zip(NAMES, paths):
            assert tree_of(path) == tree_of(SHIPPED / f"{name}.tar.gz") == LOCK[name]["tree"], name
            with tarfile.open(path) as t:
                assert all(m.name.split("/")[0] == name for m in t.getmembers()), name
        first = [sha256(p) for p in paths]
        for p in paths:
            os.remove(p)
        r = run(*base, "path", *NAMES)
        assert r.returncode == 0 and [sha256(p) for p in paths] == first, r.stderr
        # Taken from the cache, the server gone.
        server.close()
        assert run(*base, "path", "mcap").returncode == 0

        # 2. No network: one line naming the source and the address.
        r = run("--search", str(empty), "--cache", str(Path(tmp, "none")), "--url", server.url, "path", "yaml-cpp")
        one_line_error(r, "yaml-cpp", "cannot download", server.url)

        # 3. A repository whose archive is not the lock's: one line, nothing cached.
        changed = github_archives("yaml-cpp")
        (url, data), = changed.items()
        with tarfile.open(fileobj=io.BytesIO(data)) as t:
            members = [(m, t.extractfile(m).read() if m.isfile() else None) for m in t.getmembers()]
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w:gz") as t:
            for i, (m, body) in enumerate(members):
                if m.name.endswith("/CMakeLists.txt") and m.name.count("/") == 1:
                    body = body + b"# one line more\n"
                    m.size = len(body)
                t.addfile(m, io.BytesIO(body) if body is not None else None)
        bad = Server({url: buf.getvalue()})
        fresh = Path(tmp, "fresh")
        r = run("--search", str(empty), "--cache", str(fresh), "--url", bad.url, "path", "yaml-cpp")
        bad.close()
        one_line_error(r, "yaml-cpp", "jbeder/yaml-cpp@f7320141120f", "files' digest")
        assert not (fresh / "yaml-cpp.tar.gz").exists()

        # 4. A tarball beside the checkout that is not the lock's: one line naming it.
        other = Path(tmp, "other")
        other.mkdir()
        (other / "mcap.tar.gz").write_bytes((SHIPPED / "mcap.tar.gz").read_bytes() + b"\0")
        r = run("--search", str(other), "--cache", str(cache), "path", "mcap")
        one_line_error(r, str(other / "mcap.tar.gz"), "sha256", LOCK["mcap"]["sha256"])

        # 5. A cached download changed since: one line, and how to mend it.
        (cache / "rmw_zenoh.tar.gz").write_bytes((SHIPPED / "mcap.tar.gz").read_bytes())
        r = run(*base, "path", "rmw_zenoh")
        one_line_error(r, "rmw_zenoh.tar.gz", "remove it to download again")

        # 6. A name the lock does not have.
        one_line_error(run(*base, "path", "rclpy"), "rclpy", "not in ros2-sources.lock")
    print(f"ros2_sources_test: 6 cases passed ({', '.join(NAMES)} downloaded from {server.url})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
