#!/usr/bin/env python3
"""Write the base scene of another arm (viewer_assets/scenes/<robot>_table.xml) from robosuite 1.4.1.

Usage: make_robot_scene.py ROBOT [ROBOT ...]   (Sawyer, IIWA, UR5e; run with scripts/setup_robosuite.sh's python)

robosuite builds its Lift environment with ROBOT (its default gripper and mount, OSC_POSE, placed
as robosuite places it on the table arena); the compiled scene's XML (what robosuite writes as
`model_file`) is written with Lift's cube removed, robosuite's assets directory replaced by
`{ASSETS}`, and the `<!-- OBJECT ASSETS -->` / `<!-- OBJECT BODIES -->` markers where
`mimicgen-sim`'s composer inserts a task's objects: the same shape as `panda_table.xml`.
"""

import os
import re
import sys

os.environ["MUJOCO_GL"] = "disable"


def main(robots):
    import robosuite

    assets = os.path.join(os.path.dirname(robosuite.__file__), "models", "assets")
    here = os.path.dirname(os.path.abspath(__file__))
    for robot in robots:
        env = robosuite.make("Lift", robots=[robot], has_renderer=False, has_offscreen_renderer=False,
                             use_camera_obs=False, ignore_done=True,
                             controller_configs=robosuite.load_controller_config(default_controller="OSC_POSE"))
        env.reset()
        xml = env.sim.model.get_xml()
        env.close()
        xml = xml.replace(assets, "{ASSETS}")
        # Lift's cube: its texture, material and body.
        xml = re.sub(r'\s*<texture[^>]*name="cube_redwood"[^>]*/>', "", xml)
        xml = re.sub(r'\s*<material[^>]*name="cube_redwood_mat"[^>]*/>', "", xml)
        body = re.search(r'\n(\s*)<body name="cube_main".*?\n\1</body>', xml, re.S)
        if body is None:
            sys.exit(f"make_robot_scene: no cube body in {robot}'s Lift scene")
        xml = xml[: body.start()] + xml[body.end():]
        xml = xml.replace("\n  </asset>", "\n    <!-- OBJECT ASSETS -->\n  </asset>", 1)
        xml = xml.replace("\n  </worldbody>", "\n    <!-- OBJECT BODIES -->\n  </worldbody>", 1)
        if "{ASSETS}" not in xml or '"cube_' in xml:
            sys.exit(f"make_robot_scene: {robot}'s scene still names the cube or no asset")
        out = os.path.join(here, "..", "viewer_assets", "scenes", f"{robot.lower()}_table.xml")
        with open(out, "w") as f:
            f.write(xml)
        print(f"make_robot_scene: wrote {os.path.relpath(out)} ({len(xml)} bytes)")


if __name__ == "__main__":
    main(sys.argv[1:] or ["Sawyer", "IIWA", "UR5e"])
