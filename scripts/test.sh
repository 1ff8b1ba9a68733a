#!/usr/bin/env bash
# Everything `make test` checks, in order, with one summary at the end and a
# non-zero exit if anything failed. Runs inside the workspace environment.
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -n "${MAGNA_ROOT:-}" ] || exec bash "$root/scripts/with_env.sh" bash "$root/scripts/test.sh" "$@"
cd "$root"

results=build/magna_test_results
rm -rf "$results" build/*/test_results
mkdir -p "$results"
failed_steps=()
step() {  # name, command...
  local name=$1; shift
  printf '\n\033[1m== %s\033[0m\n' "$name"
  "$@" || failed_steps+=("$name")
}

# ROS and MAGNA processes alive now; any new one still alive after the tests is a leak.
ros_processes() { ps -eo pid=,stat=,args= | awk '$2 !~ /^Z/' | grep -E 'ros(master|launch|out|test)|magna|/devel/' \
                  | grep -v -E 'grep|scripts/test.sh|with_env.sh' | awk '{print $1}' | sort; }
before_pids=$(ros_processes)
no_leftovers() {
  sleep 1  # let processes that are ending finish
  local leaked
  leaked=$(comm -13 <(echo "$before_pids") <(ros_processes))
  [ -z "$leaked" ] && return 0
  echo "processes started by the tests are still running:" >&2
  for pid in $leaked; do ps -o pid=,args= -p "$pid" >&2; done
  return 1
}

step "ruff" ruff check .
step "catkin_lint" catkin_lint -W2 --strict --offline --quiet src
if [ "${1:-}" != "--lint-only" ]; then
  step "pytest (unit and live-master tests)" python -m pytest -q --junitxml="$results/pytest.xml"
  step "catkin test (gtest and rostest)" catkin test --no-status --summarize
  step "no process left behind" no_leftovers
fi

python scripts/test_summary.py "$results" build/*/test_results
summary_status=$?
if [ ${#failed_steps[@]} -gt 0 ]; then
  echo "failed steps: ${failed_steps[*]}" >&2
  exit 1
fi
exit $summary_status
