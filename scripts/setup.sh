#!/usr/bin/env bash
# One-command set-up of the MAGNA workspace on Debian 12: Debian packages, the
# project's venv, the catkin configuration and build. Idempotent: each step
# checks first and does nothing when its work is already done.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
say() { printf '\033[1m[setup]\033[0m %s\n' "$*"; }

# --- 1. Debian packages --------------------------------------------------------
apt_list="${MAGNA_APT_LIST:-scripts/apt-packages.txt}"  # overridable for tests
[ -r "$apt_list" ] || { echo "setup: cannot read the package list $apt_list" >&2; exit 2; }
mapfile -t apt_wanted < <(sed -e 's/#.*//' -e '/^[[:space:]]*$/d' "$apt_list")
apt_missing=()
while read -r name status; do
  [ "$status" = "ii" ] || apt_missing+=("$name")
done < <(for p in "${apt_wanted[@]}"; do
           s=$(dpkg-query -W -f='${db:Status-Abbrev}' "$p" 2>/dev/null | tr -d ' ' || true)
           echo "$p ${s:-none}"
         done)
if [ ${#apt_missing[@]} -gt 0 ]; then
  cmd="apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends ${apt_missing[*]}"
  if [ "$(id -u)" -ne 0 ]; then
    echo "setup: ${#apt_missing[@]} Debian packages are missing and installing them needs root. Run:" >&2
    echo "  sudo sh -c '$cmd'" >&2
    echo "then run 'make setup' again." >&2
    exit 1
  fi
  say "installing ${#apt_missing[@]} Debian packages: ${apt_missing[*]}"
  sh -c "$cmd"
fi

# --- 2. The venv ---------------------------------------------------------------
if [ ! -x .venv/bin/python ]; then
  say "creating .venv from /usr/bin/python3 (with system site-packages, for rospy)"
  /usr/bin/python3 -m venv --system-site-packages .venv
fi
req_hash=$(sha256sum requirements.txt | cut -d' ' -f1)
if [ "$(cat .venv/.requirements.sha256 2>/dev/null || true)" != "$req_hash" ]; then
  say "installing Python requirements into .venv"
  find_links=()
  [ -d /opt/wheels ] && find_links=(--find-links /opt/wheels)  # the local CPU torch wheel
  .venv/bin/pip install --disable-pip-version-check "${find_links[@]}" -r requirements.txt
  echo "$req_hash" > .venv/.requirements.sha256
fi

# --- 3. catkin -----------------------------------------------------------------
if [ ! -d .catkin_tools ]; then
  say "initialising the catkin workspace"
  catkin init >/dev/null
fi
# Without an explicit interpreter CMake may pick another python3 on PATH and fail on catkin_pkg.
catkin config --source-space src --devel-space devel --build-space build --install-space install \
  --cmake-args -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release >/dev/null
stamp=build/.magna_build_stamp
# Rebuild only when something catkin turns into build products changed (new Python
# modules in a package need no rebuild: the devel space points at src/).
build_inputs() {
  find src CMakeLists.txt -type f -newer "$stamp" \( -name package.xml -o -name CMakeLists.txt -o -name setup.py \
    -o -name '*.msg' -o -name '*.srv' -o -name '*.action' -o -name '*.cpp' -o -name '*.h' -o -name '*.hpp' \
    -o -name '*.in' -o -name '*.cmake' -o -path '*/nodes/*' -o -path '*/scripts/*' \) -print -quit
}
if [ ! -f devel/setup.bash ] || [ ! -f "$stamp" ] || [ -n "$(build_inputs)" ]; then
  say "catkin build"
  catkin build --no-status --summarize -j"$(nproc)"
  touch "$stamp"
fi
# --- 4. The studio's page assets (npm, from the registry at set-up time only) ------
web=src/magna_studio/web
lock_hash=$(sha256sum "$web/package-lock.json" | cut -d' ' -f1)
if [ "$(cat "$web/node_modules/.magna_lock.sha256" 2>/dev/null || true)" != "$lock_hash" ]; then
  if ! command -v npm >/dev/null; then
    if [ "$(id -u)" -ne 0 ]; then
      echo "setup: npm is missing; install it (sudo apt-get install nodejs npm), then run 'make setup' again" >&2
      exit 1
    fi
    say "installing nodejs and npm (the studio's page assets come from the npm registry)"
    apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends nodejs npm
  fi
  say "installing the studio's page assets (npm ci in $web)"
  (cd "$web" && npm ci --no-audit --no-fund --loglevel=error)
  # three's package marks some of its sources executable; they are data the page loads, and catkin_lint
  # (make test) refuses executables a package does not install
  find "$web/node_modules" -path '*/.bin' -prune -o -type f -perm /111 -exec chmod a-x {} +
  echo "$lock_hash" > "$web/node_modules/.magna_lock.sha256"
fi
say "ready: ./magna --help, make run, make test"
