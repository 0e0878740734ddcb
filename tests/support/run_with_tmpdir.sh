#!/bin/sh
# Runs one test with a temporary folder of its own as TMPDIR, removed when the
# test ends, whatever its outcome: what a test (or a process it starts)
# writes to its temporary folder never outlives it, and tests running side by
# side never share one. CTest runs every test through this (cmake/VlocHelpers.cmake).
#   run_with_tmpdir.sh NAME COMMAND [ARGS...]
name="$1"
shift
dir=$(mktemp -d "${TMPDIR:-/tmp}/vloc_test_${name}.XXXXXX") || exit 1
TMPDIR="$dir" "$@"
rc=$?
rm -rf "$dir"
exit $rc
