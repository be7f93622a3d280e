#!/bin/bash
# snap.sh NAME: copy of the worktree's tree (committed + uncommitted) as /tmp/flying-x/NAME
n=$1; rm -rf /tmp/flying-x/$n; mkdir -p /tmp/flying-x/$n /tmp/flying-x/$n.pkg
cd /work/wt-flying && git ls-files -co --exclude-standard | grep -v '^\.venv' | tar cf - -T - | tar xf - -C /tmp/flying-x/$n
ln -sfn /tmp/flying-x/$n /tmp/flying-x/$n.pkg/touchdown
printf '#!/bin/sh\nPYTHONPATH=/tmp/flying-x/%s.pkg exec /work/wt-flying/.venv/bin/python "$@"\n' $n > /tmp/flying-x/$n.py; chmod +x /tmp/flying-x/$n.py
