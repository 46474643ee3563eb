#!/usr/bin/env bash
# Fail if any tracked C++ file differs from what clang-format (the repo's .clang-format) makes
# of it; `make format` fixes them. Checks the repository this script is in.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang-format >/dev/null || {
  echo "check_format: clang-format not found; run scripts/setup.sh (Debian package clang-format)" >&2
  exit 1
}
mapfile -t files < <(git ls-files '*.cpp' '*.hpp')
if out=$(clang-format --dry-run --Werror "${files[@]}" 2>&1); then
  echo "check_format: ${#files[@]} files clang-formatted"
  exit 0
fi
# Diagnostics read "FILE:LINE:COL: error: code should be clang-formatted [...]".
mapfile -t bad < <(grep -oE '^[^:]+:[0-9]+:[0-9]+: error' <<<"$out" | cut -d: -f1 | sort -u)
if ((${#bad[@]} == 0)); then
  echo "$out" >&2
  echo "check_format: clang-format failed" >&2
  exit 1
fi
printf 'check_format: not clang-formatted: %s\n' "${bad[@]}" >&2
echo "check_format: ${#bad[@]} of ${#files[@]} files differ from clang-format" \
  "($(clang-format --version)); run \`make format\`" >&2
exit 1
