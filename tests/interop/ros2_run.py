#!/usr/bin/env python3
"""What `ros2 run PKG EXECUTABLE [ARGS...]` does, without the ros2 CLI (no wheel has it):
find the package's install prefix through the ament index (AMENT_PREFIX_PATH, as set by a
workspace's install/setup.bash), take PREFIX/lib/PKG/EXECUTABLE, and exec it with ARGS.

    python ros2_run.py tracer_calib tracer_calib_node --ros-args --params-file F
    python ros2_run.py --which tracer_calib tracer_calib_node     # print the path only

Exit status 1 with one line when the package or executable is not found.
"""

import os
import sys

from ament_index_python.packages import PackageNotFoundError, get_package_prefix


def executable_path(package, executable):
    try:
        prefix = get_package_prefix(package)
    except PackageNotFoundError:
        raise SystemExit(f"ros2_run.py: package '{package}' not found (is the workspace's install/setup.bash sourced?)")
    path = os.path.join(prefix, "lib", package, executable)
    if not (os.path.isfile(path) and os.access(path, os.X_OK)):
        raise SystemExit(f"ros2_run.py: no executable '{executable}' in {os.path.join(prefix, 'lib', package)}")
    return path


def main(argv):
    which = argv[:1] == ["--which"]
    if which:
        argv = argv[1:]
    if len(argv) < 2:
        raise SystemExit("usage: ros2_run.py [--which] PKG EXECUTABLE [ARGS...]")
    path = executable_path(argv[0], argv[1])
    if which:
        print(path)
        return
    os.execv(path, [path] + argv[2:])


if __name__ == "__main__":
    main(sys.argv[1:])
