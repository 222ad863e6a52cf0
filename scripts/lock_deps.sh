#!/usr/bin/env bash
# Refresh requirements/constraints.txt: the exact set of versions the test suite passed on.
#
# Resolves the newest versions that pyproject.toml's ranges allow in a fresh venv (no
# constraints), runs the whole test suite there, and only if it passes writes `pip freeze` of
# that venv as the new constraints file. torch is pinned to 2.13.0 (the CPU build; see README).
#   scripts/lock_deps.sh            # writes requirements/constraints.txt (refuses to overwrite
#   scripts/lock_deps.sh --force    # an existing file without --force)
set -euo pipefail
cd "$(dirname "$0")/.."
out=requirements/constraints.txt
if [[ -e $out && "${1:-}" != "--force" ]]; then
  echo "lock_deps: $out exists; pass --force to replace it" >&2
  exit 2
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python3 -m venv "$tmp/venv"
# shellcheck disable=SC1091
. "$tmp/venv/bin/activate"
python -m pip install -q --upgrade pip
python -m pip install -q torch==2.13.0
python -m pip install -q -e ".[all]"
MPLBACKEND=Agg python -m pytest -q -p no:cacheprovider
{
  echo "# Versions the test suite passed on (Python $(python -c 'import sys; print(sys.version.split()[0])'), $(date -u +%Y-%m-%d))."
  echo "# Made by scripts/lock_deps.sh; install with: pip install -c $out -e \".[all]\""
  python -m pip freeze --exclude-editable | grep -v -i '^mrexplore' | sed 's/+cpu$//'
} > "$tmp/constraints.txt"
mkdir -p "$(dirname "$out")"
mv "$tmp/constraints.txt" "$out"
echo "lock_deps: wrote $out ($(grep -vc '^#' "$out") packages)"
