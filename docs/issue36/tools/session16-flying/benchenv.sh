export NUMBA_CPU_NAME=znver3 NUMBA_CPU_FEATURES="$(cat /tmp/flying-x/feat.txt)" PYTHONHASHSEED=0
