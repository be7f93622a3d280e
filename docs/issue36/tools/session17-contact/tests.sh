#!/bin/bash
cd /work/wt-contact
echo "golden start $(date -u +%T) $(git rev-parse --short HEAD)"
.venv/bin/pytest -n 2 -p no:cacheprovider -q tests/test_golden.py > /tmp/contact-x/t-golden.log 2>&1; echo "golden rc ${PIPESTATUS[0]} $? $(date -u +%T)"
.venv/bin/pytest -n 2 -m "not redis and not slow" -p no:cacheprovider -q > /tmp/contact-x/t-fast.log 2>&1; echo "fast rc $? $(date -u +%T)"
.venv/bin/pytest -n 2 -m "not redis" -p no:cacheprovider -q tests/test_edges3d.py tests/test_edges.py tests/test_reference3d.py tests/test_bounce_reference.py tests/test_energy.py tests/test_transitions.py tests/test_models.py tests/test_friction.py tests/test_friction_law.py tests/test_topple.py tests/test_rotation_tiny.py > /tmp/contact-x/t-ref.log 2>&1; echo "ref rc $? $(date -u +%T)"
