#!/usr/bin/env bash
# The C++ sources follow .clang-format (docs/conventions.md): lists the files that
# do not, with the command that fixes them. Part of the test suite (ctest: format).
#   scripts/check/format.sh          check
#   scripts/check/format.sh --fix    format the tree in place
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
command -v clang-format >/dev/null || { echo "check_format: clang-format is missing (scripts/setup.sh installs it)" >&2; exit 1; }
mapfile -t listed < <(git ls-files --cached --others --exclude-standard '*.cc' '*.h' 2>/dev/null || find cli core server client wire tests -name '*.cc' -o -name '*.h')
files=()
for f in "${listed[@]}"; do [ -f "$f" ] && files+=("$f"); done  # not files deleted in the work tree
if [ "${1:-}" = "--fix" ]; then
  clang-format -i "${files[@]}"
  exit 0
fi
bad=()
for f in "${files[@]}"; do
  clang-format --dry-run -Werror "$f" >/dev/null 2>&1 || bad+=("$f")
done
if ((${#bad[@]})); then
  printf 'check_format: not formatted: %s\n' "${bad[@]}" >&2
  echo "check_format: run scripts/check/format.sh --fix" >&2
  exit 1
fi
echo "check_format: ${#files[@]} files formatted"
