#!/bin/bash
# An uncompiled copy of the step, for reading a run piece by piece (MODEL-NOTES 58).
#
#   docs/issue35/tools/uncompiled/make.sh /tmp/plain        # from the checkout this script is in
#   TD_PY=1 PYTHONPATH=/tmp/plain.pkg .venv/bin/python my_script.py
#
# The copy's kernels are plain Python (the decorators of sim/compiled.py replaced by the identity,
# the scratch arrays by np.zeros, the records read as numpy recarrays): it gives the compiled
# run's bits (start 118 of tests/test_edges3d.py's sample: the same final position to the last
# digit) at about 0.6 s for a 3 s touchdown, and any print() works inside it (numba's print in
# the compiled step hangs the run). Without TD_PY=1 the copy compiles as usual.
set -e
src="$(cd "$(dirname "$0")/../../../.." && pwd)"
dest="$1"
rm -rf "$dest"; mkdir -p "$dest"
(cd "$src" && git ls-files -z | xargs -0 tar cf - --files-from=- 2>/dev/null) | tar xf - -C "$dest"
(cd "$dest" && patch -s -p1 < "$src/docs/issue35/tools/uncompiled/uncompiled.patch")
mkdir -p "$dest.pkg"; ln -sfn "$dest" "$dest.pkg/touchdown"
echo "$dest.pkg"
