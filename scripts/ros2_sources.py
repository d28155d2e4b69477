#!/usr/bin/env python3
"""The stock ROS 2 sources the tests build, by hash (ros2-sources.lock, docs/ros2-sources.md).

    ros2_sources.py path NAME...   the verified tarball of each, one path a line
    ros2_sources.py check          every source of the lock: where it is, or that it is absent
    ros2_sources.py lock DIR       (maintainers) the lock's hashes from the tarballs in DIR

Each source is a `git archive` of named commits of public repositories, packed as
NAME.tar.gz (one folder NAME/). `path` looks in $TRACER_ROS2_SRC, then ../shared/ros2-src/
beside the checkout: a tarball found there must have the lock's sha256. Else it takes the
copy downloaded before into ~/.cache/tracer_calib/ros2-src/, or downloads each commit from
its repository (https://github.com/REPO/archive/COMMIT.tar.gz), keeps the paths the lock
names, and checks the files' digest (`tree`: a download is packed differently, its files
are the same) before it packs NAME.tar.gz there. A mismatch, or a source that cannot be
had, stops with one line naming it (exit 1).

`tree` is the sha256 of the sorted lines `KIND SHA256 PATH` of the archive's files under
NAME/ (KIND `f` a file, `x` an executable, `l` a symlink, whose SHA256 is that of its
target). Options (for the tests): --search DIR (instead of the two folders; repeatable),
--cache DIR, --url BASE (instead of https://github.com).
"""

import argparse
import gzip
import hashlib
import io
import os
import sys
import tarfile
import tomllib
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LOCK = ROOT / "ros2-sources.lock"
PROG = "ros2_sources"


class Stop(Exception):
    """One line for the user, then exit 1."""


def sha256_file(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def entries(tar, strip):
    """(path below the first `strip` components, kind, sha256, member, data) of the files."""
    for m in tar.getmembers():
        parts = m.name.split("/")
        if len(parts) <= strip or not parts[strip]:
            continue
        rel = "/".join(parts[strip:])
        if m.issym():
            yield rel, "l", hashlib.sha256(m.linkname.encode()).hexdigest(), m, None
        elif m.isfile():
            data = tar.extractfile(m).read()
            kind = "x" if m.mode & 0o111 else "f"
            yield rel, kind, hashlib.sha256(data).hexdigest(), m, data


def tree_digest(items):
    lines = sorted(f"{kind} {digest} {rel}" for rel, kind, digest, *_ in items)
    return hashlib.sha256("\n".join(lines).encode()).hexdigest()


def tarball_tree(path):
    with tarfile.open(path) as tar:
        return tree_digest(entries(tar, 1))


def kept(rel, part):
    """Whether a path of a part's archive is in the source (the lock's include/exclude)."""
    under = lambda p: rel == p or rel.startswith(p.rstrip("/") + "/")
    if part.get("include") and not any(under(p) for p in part["include"]):
        return False
    return not any(under(p) for p in part.get("exclude", []))


def download(name, source, base):
    """The files of every part of a source, from its repository's archives."""
    items = []
    for part in source["parts"]:
        url = f"{base.rstrip('/')}/{part['repository']}/archive/{part['commit']}.tar.gz"
        try:
            with urllib.request.urlopen(url, timeout=120) as r:
                data = r.read()
            tar = tarfile.open(fileobj=io.BytesIO(data))
        except (OSError, tarfile.TarError) as e:
            raise Stop(f"{PROG}: {name}: cannot download {url}: {e}") from e
        prefix = part.get("prefix", "")
        for rel, kind, digest, m, payload in entries(tar, 1):
            if kept(rel, part):
                items.append((f"{prefix}/{rel}" if prefix else rel, kind, digest, m, payload))
    return items


def pack(name, items, out):
    """NAME.tar.gz of `items`, the same bytes every time (mtime 0, sorted, owner 0)."""
    tmp = out.with_suffix(".tmp")
    with open(tmp, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", mtime=0) as gz:
        with tarfile.open(fileobj=gz, mode="w", format=tarfile.PAX_FORMAT) as tar:
            for rel, kind, _, m, payload in sorted(items, key=lambda i: i[0]):
                info = tarfile.TarInfo(f"{name}/{rel}")
                info.mtime, info.uid, info.gid, info.uname, info.gname = 0, 0, 0, "", ""
                if kind == "l":
                    info.type, info.linkname, info.mode = tarfile.SYMTYPE, m.linkname, 0o777
                    tar.addfile(info)
                else:
                    info.size, info.mode = len(payload), 0o755 if kind == "x" else 0o644
                    tar.addfile(info, io.BytesIO(payload))
    os.replace(tmp, out)


def load_lock():
    try:
        with open(LOCK, "rb") as f:
            return tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise Stop(f"{PROG}: {LOCK}: {e}") from e


def search_dirs(args):
    if args.search:
        return [Path(d) for d in args.search]
    dirs = [Path(os.environ["TRACER_ROS2_SRC"])] if os.environ.get("TRACER_ROS2_SRC") else []
    return dirs + [ROOT.parent / "shared" / "ros2-src"]


def cache_dir(args):
    if args.cache:
        return Path(args.cache)
    top = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(top) / "tracer_calib" / "ros2-src"


def resolve(name, lock, args, fetch=True):
    """The verified tarball of `name` (None if absent and `fetch` is off)."""
    source = lock.get(name)
    if not isinstance(source, dict) or "parts" not in source:
        raise Stop(f"{PROG}: {name}: not in {LOCK.name}")
    for d in search_dirs(args):
        path = d / f"{name}.tar.gz"
        if path.is_file():
            got = sha256_file(path)
            if got != source["sha256"]:
                raise Stop(f"{PROG}: {path}: sha256 {got}, {LOCK.name} says {source['sha256']}")
            return path
    cached = cache_dir(args) / f"{name}.tar.gz"
    if cached.is_file():
        got = tarball_tree(cached)
        if got != source["tree"]:
            raise Stop(f"{PROG}: {cached}: files' digest {got}, {LOCK.name} says {source['tree']} (remove it to download again)")
        return cached
    if not fetch:
        return None
    base = args.url or os.environ.get("TRACER_ROS2_SRC_URL") or "https://github.com"
    items = download(name, source, base)
    got = tree_digest(items)
    if got != source["tree"]:
        commits = " + ".join(f"{p['repository']}@{p['commit'][:12]}" for p in source["parts"])
        raise Stop(f"{PROG}: {name}: the download of {commits} has files' digest {got}, {LOCK.name} says {source['tree']}")
    cached.parent.mkdir(parents=True, exist_ok=True)
    pack(name, items, cached)
    return cached


def main(argv):
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n")[0])
    p.add_argument("--search", action="append", help="look for NAME.tar.gz here (repeatable)")
    p.add_argument("--cache", help="where downloads are kept")
    p.add_argument("--url", help="base of the repositories' archives (default https://github.com)")
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("path").add_argument("names", nargs="+")
    sub.add_parser("check")
    sub.add_parser("lock").add_argument("dir")
    args = p.parse_args(argv)
    try:
        if args.cmd == "path":
            lock = load_lock()
            for name in args.names:
                print(resolve(name, lock, args))
        elif args.cmd == "check":
            lock = load_lock()
            for name in lock:
                where = resolve(name, lock, args, fetch=False)
                print(f"{name}: {where}" if where else f"{name}: absent (downloaded when a test needs it)")
        else:
            write_lock(Path(args.dir))
    except Stop as e:
        print(e, file=sys.stderr)
        return 1
    return 0


def write_lock(d):
    """Rewrite the lock's sha256 and tree lines from the tarballs in `d` (the rest kept)."""
    lines, name = [], None
    for line in LOCK.read_text().splitlines():
        s = line.strip()
        if s.startswith("[") and s.endswith("]") and not s.startswith("[["):
            name = s.strip("[]").strip('"')
        elif name and s.startswith("sha256 ="):
            line = f'sha256 = "{sha256_file(d / f"{name}.tar.gz")}"'
        elif name and s.startswith("tree ="):
            line = f'tree = "{tarball_tree(d / f"{name}.tar.gz")}"'
        lines.append(line)
    LOCK.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
