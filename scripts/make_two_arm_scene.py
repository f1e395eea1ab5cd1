#!/usr/bin/env python3
"""Write the base scene of a robosuite 1.4.1 two-arm task (viewer_assets/scenes/<task>_table.xml).

Usage: make_two_arm_scene.py [TASK ...]   (TwoArmLift; run with scripts/setup_robosuite.sh's python)

robosuite builds the task's environment with two Pandas in the configuration the environment
defines by default (TwoArmLift: "single-arm-opposed", the arms facing each other across the
table), OSC_POSE for each; the compiled scene's XML (what robosuite writes as `model_file`) is
written with the task's objects removed, robosuite's assets directory replaced by `{ASSETS}`, and
the `<!-- OBJECT ASSETS -->` / `<!-- OBJECT BODIES -->` markers where `mimicgen-sim`'s composer
inserts a task's objects: the shape of `panda_table.xml`, with robot0_/gripper0_/mount0_ and
robot1_/gripper1_/mount1_ as robosuite names them.
"""

import os
import re
import sys

os.environ["MUJOCO_GL"] = "disable"

# Per task: the root bodies of its objects, and the asset names (textures, materials, meshes)
# only they use.
TASKS = {
    "TwoArmLift": {"bodies": ["pot_root"], "assets": r'name="pot_[^"]*"'},
}


def main(tasks):
    import robosuite

    assets = os.path.join(os.path.dirname(robosuite.__file__), "models", "assets")
    here = os.path.dirname(os.path.abspath(__file__))
    for task in tasks:
        spec = TASKS.get(task)
        if spec is None:
            sys.exit(f"make_two_arm_scene: no object list for {task} (known: {', '.join(TASKS)})")
        env = robosuite.make(task, robots=["Panda", "Panda"], has_renderer=False, has_offscreen_renderer=False,
                             use_camera_obs=False, ignore_done=True,
                             controller_configs=robosuite.load_controller_config(default_controller="OSC_POSE"))
        env.reset()
        xml = env.sim.model.get_xml()
        configuration = env.env_configuration
        env.close()
        xml = xml.replace(assets, "{ASSETS}")
        xml = re.sub(r'\s*<(texture|material|mesh)[^>]*' + spec["assets"] + r'[^>]*/>', "", xml)
        for root in spec["bodies"]:
            body = re.search(r'\n(\s*)<body name="' + re.escape(root) + r'".*?\n\1</body>', xml, re.S)
            if body is None:
                sys.exit(f"make_two_arm_scene: no body {root} in {task}'s scene")
            xml = xml[: body.start()] + xml[body.end():]
        xml = xml.replace("\n  </asset>", "\n    <!-- OBJECT ASSETS -->\n  </asset>", 1)
        xml = xml.replace("\n  </worldbody>", "\n    <!-- OBJECT BODIES -->\n  </worldbody>", 1)
        for root in spec["bodies"]:
            if f'"{root}"' in xml:
                sys.exit(f"make_two_arm_scene: {task}'s scene still names {root}")
        if "{ASSETS}" not in xml or "robot1_base" not in xml:
            sys.exit(f"make_two_arm_scene: {task}'s scene has no asset or no second arm")
        name = re.sub(r"(?<!^)(?=[A-Z])", "_", task).lower()
        out = os.path.join(here, "..", "viewer_assets", "scenes", f"{name}_table.xml")
        with open(out, "w") as f:
            f.write(xml)
        print(f"make_two_arm_scene: wrote {os.path.relpath(out)} ({len(xml)} bytes, {configuration})")


if __name__ == "__main__":
    main(sys.argv[1:] or list(TASKS))
