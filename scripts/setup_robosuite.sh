#!/usr/bin/env bash
# One-time (idempotent) setup of a Python environment with robosuite 1.4.1 and MuJoCo 2.3.2, the
# versions the reference MimicGen datasets were made with, for scripts/robosuite_replay.py.
# It lands in $MIMICGEN_CACHE/venv-robosuite (default ~/.cache/mimicgen), separate from
# scripts/setup.sh's venv (which pins numpy 2, which robosuite 1.4.1's numba stack does not take).
# A second call with unchanged requirements returns at once.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cache="${MIMICGEN_CACHE:-$HOME/.cache/mimicgen}"
mkdir -p "$cache"

venv="$cache/venv-robosuite"
stamp="$venv/.requirements.sha256"
want="$(sha256sum "$here/requirements-robosuite.txt" | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup_robosuite: creating Python environment in $venv"
  python3 -m venv --clear "$venv"
  # --no-deps: the requirements file is the full pinned set (see its header); wheels only.
  "$venv/bin/pip" install -q --disable-pip-version-check --no-deps --only-binary=:all: \
    -r "$here/requirements-robosuite.txt"
  site="$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  # robosuite's documented override file: without it robosuite forces MUJOCO_GL=egl at import
  # (MUJOCO_GPU_RENDERING) and needs libEGL even when nothing renders; scripts that render set
  # MUJOCO_GL=egl themselves.
  printf '%s\n' '# Written by scripts/setup_robosuite.sh: no rendering in this environment.' \
    'MUJOCO_GPU_RENDERING = False' > "$site/robosuite/macros_private.py"
  # Smoke test; it also fills numba's cache of robosuite's jitted functions (about 10 s once).
  MUJOCO_GL=disable "$venv/bin/python" - <<'PY'
import numpy as np
import robosuite
env = robosuite.make("Stack", robots=["Panda"], has_renderer=False, has_offscreen_renderer=False,
                     use_camera_obs=False, ignore_done=True, hard_reset=False,
                     controller_configs=robosuite.load_controller_config(default_controller="OSC_POSE"))
env.reset()
env.reset_from_xml_string(env.edit_model_xml(env.sim.model.get_xml()))
for t in range(3):
    env.step(np.full(env.action_dim, 0.1 * (-1) ** t))
env._check_success()
env.close()
print(f"setup_robosuite: robosuite {robosuite.__version__} steps a Stack env")
PY
  echo "$want" > "$stamp"
fi
echo "setup_robosuite: ok ($venv)"
