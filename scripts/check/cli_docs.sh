#!/usr/bin/env bash
# docs/cli.md must have a heading for every command `orbatlas --help` lists and
# every benchmark `orbatlas bench --help` lists, and name no command the tool does
# not have. Part of the test suite (ctest: cli_docs).
#   scripts/check/cli_docs.sh [BUILD_DIR]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="${1:-${ORBATLAS_BUILD_DIR:-$ROOT/build}}"
TOOL="$BUILD/client/orbatlas"
DOC="$ROOT/docs/cli.md"
subcommands() { "$@" --help | sed -n '/^Subcommands:/,$p' | awk 'NR > 1 && NF { print $1 }'; }
expected=()
for c in $(subcommands "$TOOL"); do
  if [ "$c" = bench ]; then
    for b in $(subcommands "$TOOL" bench); do expected+=("bench $b"); done
  else
    expected+=("$c")
  fi
done
missing=0
for c in "${expected[@]}"; do
  grep -qF "### \`orbatlas $c\`" "$DOC" || { echo "check_cli_docs: docs/cli.md has no section for 'orbatlas $c'" >&2; missing=1; }
done
# Headings for commands that do not exist (renamed or removed).
while IFS= read -r heading; do
  found=0
  for c in "${expected[@]}"; do [ "$heading" = "$c" ] && found=1; done
  [ "$found" = 1 ] || { echo "check_cli_docs: docs/cli.md documents 'orbatlas $heading', which the tool does not have" >&2; missing=1; }
done < <(sed -n 's/^### `orbatlas \(.*\)`$/\1/p' "$DOC")
[ "$missing" = 0 ] && echo "check_cli_docs: ${#expected[@]} commands, all documented"
exit "$missing"
