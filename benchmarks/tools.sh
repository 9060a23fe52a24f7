# Sourced by the scripts that train, evaluate or sweep from a shell (benchmarks/*.sh,
# experiments/*.sh), in the repository's root.

# use_tools: BIN, the folder holding the python and franka-composer they run (the user's;
# else the repository's venv, `make setup`'s; else the ones on PATH, a pip install's), one
# thread per process, and MENAGERIE_ROOT as the Makefile chooses it: the user's; else the
# copy beside the repository where it holds the Panda (machines without internet); else
# none, and the package takes mujoco-menagerie's cache or downloads the Panda.
use_tools() {
  if [ -z "${BIN:-}" ]; then
    if [ -x .venv/bin/franka-composer ]; then
      BIN=.venv/bin
    elif command -v franka-composer >/dev/null; then
      BIN=$(dirname "$(command -v franka-composer)")
    fi
  fi
  if [ ! -x "${BIN:-.venv/bin}/franka-composer" ] || [ ! -x "${BIN:-.venv/bin}/python" ]; then
    echo "no franka-composer and python in ${BIN:-.venv/bin}: run make setup, or set BIN to" \
         "the bin folder of the virtualenv you installed franka_composer into" >&2
    return 1
  fi
  BIN=$(realpath -m "$BIN")
  export OMP_NUM_THREADS=1
  if [ -z "${MENAGERIE_ROOT:-}" ] && [ -d ../shared/menagerie/franka_emika_panda ]; then
    MENAGERIE_ROOT=$(cd .. && pwd)/shared/menagerie
    export MENAGERIE_ROOT
  fi
}
