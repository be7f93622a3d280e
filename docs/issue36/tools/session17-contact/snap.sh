#!/bin/bash
# snap.sh NAME: the worktree's tree (committed + uncommitted) as /tmp/contact-x/NAME (+ NAME.pkg, NAME.py)
n=$1; rm -rf /tmp/contact-x/$n; mkdir -p /tmp/contact-x/$n /tmp/contact-x/$n.pkg
cd /work/wt-contact && git ls-files -co --exclude-standard | grep -v '^\.venv' | tar cf - -T - | tar xf - -C /tmp/contact-x/$n
ln -sfn /tmp/contact-x/$n /tmp/contact-x/$n.pkg/touchdown
printf '#!/bin/sh\nPYTHONPATH=/tmp/contact-x/%s.pkg exec /work/main/.venv/bin/python "$@"\n' $n > /tmp/contact-x/$n.py; chmod +x /tmp/contact-x/$n.py
