#!/bin/bash
# tree.sh COMMIT|DIR TAG: $KPROF/TAG, the tree to measure (PYTHONPATH=$KPROF/TAG.pkg); DIR: a
# worktree, its uncommitted changes included
set -eu
src=$1; tag=$2; dst=$KPROF/$tag
rm -rf "$dst" "$dst.pkg"; mkdir -p "$dst" "$dst.pkg"
if [ -d "$src" ]; then
    (cd "$src" && git ls-files -co --exclude-standard | grep -v '^\.venv' | tar cf - -T -) \
        | tar xf - -C "$dst"
else
    git -C "$(git -C "$(dirname "$0")" rev-parse --show-toplevel)" archive "$src" | tar x -C "$dst"
fi
ln -sfn "$dst" "$dst.pkg/touchdown"
# $KPROF/TAG.py: the tree's interpreter, for bench/states.py --against and CPU-time runs
printf '#!/bin/sh\nPYTHONPATH=%s.pkg exec %s "$@"\n' "$dst" "$KPROF_PY" > "$dst.py"
chmod +x "$dst.py"
echo "$dst"
