#!/usr/bin/env bash
# Set-up and entry point, in one: the first run installs what mimarble needs
# (libLLVM >= 16 via apt when run as root, then a virtual environment .venv with
# the package and its test tools); every run then does what was asked.
#
#   ./go test [PYTEST ARGS]     run the test suite (pytest), in the checkout
#   ./go COMMAND [ARGS]         run `mimarble COMMAND`, e.g. ./go render scenes/fig11a.scene -o m.png
#   ./go python [ARGS]          the environment's Python
# Paths in COMMAND's and python's arguments are relative to where you stand, as usual.
# ./go, ./go -h and ./go --help print this usage, then mimarble's own --help.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="$here/.venv"
python="${PYTHON:-python3}"

# 1. A libLLVM Dr.Jit 1.5 can use (>= 16; Debian's 15 aborts the process, 14 is refused).
#    mimarble.runtime.environment finds it; it imports nothing beyond the standard library.
have_llvm() {
    "$python" - "$here/mimarble/runtime/environment.py" <<'PY'
import runpy, sys
sys.exit(0 if runpy.run_path(sys.argv[1])["search_libllvm"]() else 1)
PY
}
if ! have_llvm; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        echo "go: installing libllvm19 (Dr.Jit needs libLLVM >= 16)" >&2
        apt-get update -qq >&2
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >&2 \
            || echo "go: could not install libllvm19; mimarble will say what it can do without it" >&2
    else
        echo "go: no libLLVM >= 16 found and cannot install it (needs root and apt-get);" \
             "mimarble will say what it can do without it" >&2
    fi
fi

# 2. The package, editable, with its test tools and every extra (the test extra pulls
#    dask and matplotlib), in .venv (redone when pyproject.toml changes).
stamp="$venv/.installed-pyproject"
if [ ! -x "$venv/bin/python" ] || ! cmp -s "$here/pyproject.toml" "$stamp"; then
    echo "go: setting up $venv" >&2
    [ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
    "$venv/bin/python" -m pip install -q --upgrade pip >&2
    # setuptools' editable install warns, in a banner, that a folder named like the package
    # may shadow it; pip shows backend warnings even with -q. Only that warning is
    # silenced (by its message): errors and every other warning still show.
    PYTHONWARNINGS="ignore:Editable installation" \
        "$venv/bin/python" -m pip install -q -e "$here[test]" >&2
    cp "$here/pyproject.toml" "$stamp"
fi

usage() {
    cat <<'USAGE'
usage: ./go test [PYTEST ARGS]   run the test suite (pytest) in the checkout;
                                 --jit-debug: with Dr.Jit's bounds checks
       ./go python [ARGS]        the environment's Python (.venv)
       ./go COMMAND [ARGS]       run `mimarble COMMAND`, e.g. ./go render fig11a -o m.png
The first run sets up .venv (and libLLVM when run as root). mimarble's own help follows.

USAGE
}

case "${1:-}" in
    test) shift; cd "$here"; exec "$venv/bin/python" -m pytest -q "$@" ;;
    python) shift; exec "$venv/bin/python" "$@" ;;
    ""|-h|--help) usage; exec "$venv/bin/python" -m mimarble --help ;;
    *) exec "$venv/bin/python" -m mimarble "$@" ;;
esac
