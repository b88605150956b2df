"""python3 -m mvkp ARGS...: runs the mvkp command-line tool with ARGS.

The binary is taken from $MVKP_CLI, else an `mvkp` executable next to this
package (build tree or a prefix's bin/), else `mvkp` on PATH. The exit code is
the tool's.
"""
import os
import shutil
import sys
from pathlib import Path


def find_cli():
    env = os.environ.get("MVKP_CLI")
    if env:
        return env
    here = Path(__file__).resolve().parent
    # <build>/python/mvkp -> <build>/mvkp; <prefix>/lib/python3/dist-packages/mvkp -> <prefix>/bin/mvkp
    for cand in (here.parent.parent / "mvkp", here.parents[3] / "bin" / "mvkp" if len(here.parents) > 3 else None):
        if cand is not None and cand.is_file() and os.access(cand, os.X_OK):
            return str(cand)
    return shutil.which("mvkp")


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    cli = find_cli()
    if not cli:
        sys.stderr.write("mvkp: the command-line tool was not found (set MVKP_CLI, or install mvkp so that it is on PATH)\n")
        return 127
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        os.execv(cli, [cli] + list(argv))  # the tool replaces this process: signals and exit code are its own
    except OSError as e:
        sys.stderr.write(f"mvkp: cannot run {cli}: {e}\n")
        return 126


if __name__ == "__main__":
    sys.exit(main())
