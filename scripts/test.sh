#!/usr/bin/env bash
# Everything `make test` checks, in order, with one summary at the end and a
# non-zero exit if anything failed. Runs inside the workspace environment.
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -n "${MAGNA_ROOT:-}" ] || exec bash "$root/scripts/with_env.sh" bash "$root/scripts/test.sh" "$@"
cd "$root"

results=build/magna_test_results
if [ "${1:-}" != "--lint-only" ]; then  # lint writes no results: it keeps the last test run's
  rm -rf "$results" build/*/test_results
fi
mkdir -p "$results"
failed_steps=()
step() {  # name, command...
  local name=$1; shift
  printf '\n\033[1m== %s\033[0m\n' "$name"
  "$@" || failed_steps+=("$name")
}

# Every process this run starts inherits the token; any still alive at the end is a leak.
export MAGNA_TEST_RUN="$$-$(date +%s%N)"
no_leftovers() {
  sleep 1  # let processes that are ending finish
  python scripts/leftover_processes.py
}

step "ruff" ruff check .
step "catkin_lint" catkin_lint -W2 --strict --offline --quiet src
step "mypy (the typed packages of pyproject.toml)" python -m mypy
step "layers (imports go down, package.xml matches)" python scripts/import_graph.py
if [ "${1:-}" != "--lint-only" ]; then
  step "pytest (unit and live-master tests)" python -m pytest -q --junitxml="$results/pytest.xml"
  step "catkin test (gtest and rostest)" catkin test --no-status --summarize --continue-on-failure
  step "no process left behind" no_leftovers
fi

summary_options=()
case "${CI:-}" in  # in CI (.ci/run sets CI) a skipped test fails the run: every test must run there
  ""|0|false|no) ;;
  *) summary_options+=(--fail-on-skip) ;;
esac
summary_status=0
if [ "${1:-}" != "--lint-only" ]; then
  python scripts/test_summary.py "${summary_options[@]}" "$results" build/*/test_results
  summary_status=$?
else  # lint writes no result files: its summary is the count of linters that passed
  lint_failed=${#failed_steps[@]}
  printf '\nlint: %d passed, %d failed (ruff, catkin_lint, mypy, layers)\n' $((4 - lint_failed)) "$lint_failed"
fi
if [ ${#failed_steps[@]} -gt 0 ]; then
  echo "failed steps: ${failed_steps[*]}" >&2
  exit 1
fi
exit $summary_status
