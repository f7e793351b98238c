#!/usr/bin/env bash
# One script, two jobs, each installing what it needs first (idempotent):
#   bash run.sh demo   install, then run `evids demo`: generate tri-modal scenarios, train, evaluate
#                      every fusion condition, sweeps, conflict study, gate sweep -> out/demo/report.html
#   bash run.sh test   install (with test extras), then run the whole test suite
# Installs: Debian libllvm19 when root with apt (Dr.Jit's fast CPU backend needs libLLVM >= 16),
# Debian chromium for the test job (the report page is checked in a headless browser), and a local
# virtual environment .venv with this package and the locked dependencies (lock/, one venv for both jobs).
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

# install_python: one .venv for both jobs, from the committed lock (lock/requirements.txt: every
# package of the base and the audio, dev, ray and tracking extras, pinned with sha256 hashes; refresh
# with `bash lock/refresh`), so demo and test share one install and every machine gets the tested
# versions. The stamp is the hash of pyproject.toml and the lock: when either changes the venv is
# rebuilt from empty, so it holds exactly the lock. A Python other than the lock's (3.11) installs
# from pyproject.toml's ranges instead, with a warning.
LOCK_EXTRAS="audio,dev,ray,svanstrom,tracking"
install_python() {
  local stamp=".venv/.installed-$(cat pyproject.toml lock/requirements.txt lock/nodeps.txt | sha256sum | cut -c1-16)"
  [ -f "$stamp" ] && return 0
  local lock_python have_python
  lock_python=$(sed -n 's/.*--python-version \([0-9.]*\).*/\1/p' lock/requirements.txt | head -1)
  have_python=$(python3 -c 'import sys; print("%d.%d" % sys.version_info[:2])')
  echo "[setup] creating .venv and installing the locked dependencies (first run takes a few minutes)"
  python3 -m venv --clear .venv
  .venv/bin/python -m pip install -q --upgrade pip >/dev/null
  # --no-compile: precompile (below) byte-compiles in parallel instead
  if [ "$have_python" = "$lock_python" ]; then
    .venv/bin/python -m pip install -q --no-compile --require-hashes --no-deps -r lock/requirements.txt
    .venv/bin/python -m pip install -q --no-compile --require-hashes --no-deps -r lock/nodeps.txt
    .venv/bin/python -m pip install -q --no-compile --no-deps -e .
  else
    echo "[setup] warning: the lock is for Python $lock_python, this is $have_python: installing the newest" \
      "versions pyproject.toml allows (untested combination)"
    .venv/bin/python -m pip install -q --no-compile -e ".[${LOCK_EXTRAS}]"
    # trackeval declares the GUI opencv-python, which would replace the headless cv2: no dependencies
    .venv/bin/python -m pip install -q --no-deps "$(grep -m1 '^trackeval==' lock/nodeps.txt | cut -d' ' -f1)"
  fi
  precompile
  touch "$stamp"
}

job="${1:-}"
case "$job" in
  demo)
    install_system
    install_python
    shift
    .venv/bin/evids demo --out out/demo "$@"
    echo "open out/demo/report.html"
    ;;
  test)
    install_system
    install_chromium
    install_python
    shift
    set +e
    bash .ci/lint      # ruff + mypy (ruff.toml, mypy.ini): seconds; a finding fails the job after the suite
    lint=$?
    # --durations=25: the slowest tests in every run's output (docs/TESTING.md says why they are slow)
    .venv/bin/python -m pytest -q -p no:cacheprovider -n 2 --durations=25 "$@"
    status=$?
    set -e
    if [ "$status" = 5 ]; then echo "error: pytest collected no tests"; exit 1; fi
    if [ "$lint" != 0 ] && [ "$status" = 0 ]; then echo "error: .ci/lint found problems (above)"; exit "$lint"; fi
    exit "$status"
    ;;
  *)
    echo "usage: bash run.sh demo|test [extra args]" >&2
    exit 2
    ;;
esac
