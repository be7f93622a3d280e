#!/bin/bash
# usage: reftests.sh LABEL
cd /work/wt-substep
L=$1
rm -f /tmp/substep/approx-$L-*.json
start=$(date +%s)
IMPACT_SUBSTEP=$L APPROXREC_OUT=/tmp/substep/approx-$L PYTHONPATH=/tmp/substep .venv/bin/pytest -n 2 -p approxrec -p no:cacheprovider -q -m "not redis" \
  tests/test_bounce_reference.py tests/test_edges.py tests/test_edges3d.py tests/test_reference3d.py \
  tests/test_friction.py tests/test_friction_law.py tests/test_topple.py tests/test_transitions.py \
  tests/test_energy.py tests/test_properties.py tests/test_determinism.py tests/test_models.py \
  tests/test_stability.py --durations=15 -rf > /tmp/substep/ref-$L.log 2>&1
echo "rc=$? wall=$(( $(date +%s) - start ))s" >> /tmp/substep/ref-$L.log
