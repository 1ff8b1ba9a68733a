#!/usr/bin/env bash
# Run a command inside the workspace environment: devel space sourced, venv first on PATH.
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source_devel() { source "$root/devel/setup.bash"; }  # a function: setup.bash must not see our arguments
source_devel
export PATH="$root/.venv/bin:$PATH" MAGNA_ROOT="$root"
cd "$root" && exec "$@"
