#!/usr/bin/env python3
"""Write the scene of a robosuite 1.4.1 two-arm task (viewer_assets/scenes/<task>.xml).

Usage: make_two_arm_scene.py [TASK ...]   (TwoArmLift, TwoArmHandover, TwoArmTransport; run with scripts/setup_robosuite.sh's python)

robosuite builds the task's environment with two Pandas in the configuration the environment
defines by default (TwoArmLift: "single-arm-opposed", the arms facing each other across the
table), OSC_POSE for each; the compiled scene's XML (what robosuite writes as `model_file`) is
written with robosuite's assets directory replaced by `{ASSETS}`: the arms as robosuite names
them (robot0_/gripper0_/mount0_, robot1_/gripper1_/mount1_) and the task's objects as robosuite
builds them (TwoArmLift's pot with handles: body `pot_root`, joint `pot_joint0`, sites
`pot_handle0`, `pot_handle1`, `pot_center`; TwoArmHandover's hammer: body `hammer_root`, geoms
`hammer_handle`, `hammer_head`, ...), so that robosuite's own environment reads the states
of what `mimicgen-sim` simulates in it.
"""

import os
import re
import sys

os.environ["MUJOCO_GL"] = "disable"

# Per task: names its scene must hold.
TASKS = {
    "TwoArmLift": ["pot_root", "pot_joint0", "pot_handle0", "pot_handle1", "pot_center", "robot1_base"],
    "TwoArmHandover": ["hammer_root", "hammer_joint0", "hammer_handle", "hammer_head", "table_top", "robot1_base"],
    "TwoArmTransport": ["payload_root", "payload_handle", "trash_main", "transport_start_bin_lid_root",
                        "transport_start_bin_lid_handle", "transport_target_bin_root", "transport_trash_bin_root",
                        "robot1_base"],
}


def main(tasks):
    import robosuite

    assets = os.path.join(os.path.dirname(robosuite.__file__), "models", "assets")
    here = os.path.dirname(os.path.abspath(__file__))
    for task in tasks:
        names = TASKS.get(task)
        if names is None:
            sys.exit(f"make_two_arm_scene: unknown task {task} (known: {', '.join(TASKS)})")
        env = robosuite.make(task, robots=["Panda", "Panda"], has_renderer=False, has_offscreen_renderer=False,
                             use_camera_obs=False, ignore_done=True,
                             controller_configs=robosuite.load_controller_config(default_controller="OSC_POSE"))
        env.reset()
        xml = env.sim.model.get_xml()
        configuration = env.env_configuration
        env.close()
        xml = xml.replace(assets, "{ASSETS}")
        missing = [n for n in names if f'"{n}"' not in xml]
        if missing or "{ASSETS}" not in xml:
            sys.exit(f"make_two_arm_scene: {task}'s scene lacks {missing or 'robosuite assets'}")
        name = re.sub(r"(?<!^)(?=[A-Z])", "_", task).lower()
        out = os.path.join(here, "..", "viewer_assets", "scenes", f"{name}.xml")
        with open(out, "w") as f:
            f.write(xml)
        print(f"make_two_arm_scene: wrote {os.path.relpath(out)} ({len(xml)} bytes, {configuration})")


if __name__ == "__main__":
    main(sys.argv[1:] or list(TASKS))
