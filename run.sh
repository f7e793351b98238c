#!/usr/bin/env bash
# One script, two jobs, each installing what it needs first (idempotent):
#   bash run.sh demo   install, then run `evids demo`: generate tri-modal scenarios, train, evaluate
#                      every fusion condition, sweeps, conflict study, gate sweep -> out/demo/report.html
#   bash run.sh test   install (with test extras), then run the whole test suite
# Installs: Debian libllvm19 when root with apt (Dr.Jit's fast CPU backend needs libLLVM >= 16),
# Debian chromium for the test job (the report page is checked in a headless browser), and a local
# virtual environment .venv with this package and its pinned dependencies.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"

have_llvm16() {
  local f
  for f in /usr/lib/*/libLLVM-1[6-9]*.so* /usr/lib/*/libLLVM-[2-9][0-9]*.so* /usr/lib/*/libLLVM.so.1[6-9]* \
           /usr/lib/llvm-1[6-9]/lib/libLLVM*.so* /usr/lib/llvm-[2-9][0-9]/lib/libLLVM*.so*; do
    [ -e "$f" ] && return 0
  done
  return 1
}

# apt_install PACKAGE WHY CONSEQUENCE: install a Debian package when root with apt, else explain.
apt_install() {
  local package="$1" why="$2" consequence="$3"
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "[setup] installing $package (apt) $why"
    apt-get update -qq >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$package" >/dev/null \
      || echo "[setup] warning: could not install $package; $consequence"
  else
    echo "[setup] warning: $package is missing and this is not root with apt; $consequence"
  fi
}

install_system() {
  have_llvm16 || apt_install libllvm19 "for Dr.Jit's fast CPU backend (libLLVM >= 16)" \
    "rendering will use Mitsuba's slow scalar variant (install LLVM 16+ to fix)"
}

install_chromium() {
  command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 \
    || apt_install chromium "for the report-page test" "the report-page browser test will be skipped"
}

# precompile: byte-compile the venv's packages on every core (pip compiles file by file on one
# core: ~70 s of a ~125 s install here), skipping the packages' own test suites and the installer
# tools, which the project never imports; .pyc files then load even under PYTHONDONTWRITEBYTECODE.
precompile() {
  .venv/bin/python -m compileall -q -j 0 -x '(/tests?/|/pip/|/setuptools/|/pygments/)' \
    .venv/lib/python3*/site-packages >/dev/null || true
}

install_python() {
  local extras="$1"
  local stamp=".venv/.installed-$(sha256sum pyproject.toml | cut -c1-16)-${extras//,/_}"
  if [ ! -x .venv/bin/python ]; then
    echo "[setup] creating .venv"
    python3 -m venv .venv
  fi
  if [ ! -f "$stamp" ]; then
    echo "[setup] installing the package and dependencies into .venv (first run takes a few minutes)"
    .venv/bin/python -m pip install -q --upgrade pip >/dev/null
    # --no-compile: precompile (below) byte-compiles in parallel instead
    .venv/bin/python -m pip install -q --no-compile -e ".[${extras}]"
    if [[ ",$extras," == *",dev,"* || ",$extras," == *",tracking,"* ]]; then
      # trackeval 1.3.0 (HOTA/CLEAR/Identity on NumPy 2) declares the GUI build opencv-python, which would
      # overwrite the headless cv2 we pin; its metrics import no cv2, so install it without dependencies
      # (its other requirements, pycocotools and tabulate, come with the extras).
      .venv/bin/python -m pip install -q --no-deps "trackeval==1.3.0"
    fi
    precompile
    rm -f .venv/.installed-*
    touch "$stamp"
  fi
}

job="${1:-}"
case "$job" in
  demo)
    install_system
    install_python "audio,tracking,svanstrom"   # tracking: trackeval for `evids demo --detection`; svanstrom: `evids sim2real`
    shift
    .venv/bin/evids demo --out out/demo "$@"
    echo "open out/demo/report.html"
    ;;
  test)
    install_system
    install_chromium
    install_python "audio,dev,ray,svanstrom"
    shift
    set +e
    .venv/bin/python -m pytest -q -p no:cacheprovider -n 2 "$@"
    status=$?
    set -e
    if [ "$status" = 5 ]; then echo "error: pytest collected no tests"; exit 1; fi
    exit "$status"
    ;;
  *)
    echo "usage: bash run.sh demo|test [extra args]" >&2
    exit 2
    ;;
esac
