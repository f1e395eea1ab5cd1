#!/usr/bin/env python3
"""What MuJoCo's SDF threads would cost Nut-and-Bolt Assembly: step time and behaviour of the
`mujoco.sdf.nut` / `mujoco.sdf.bolt` plugin shapes against the primitive nut and bolt the task uses.

Usage: python sdf_nutbolt.py [--steps N]

Needs the MuJoCo 3.17.0 Python package (the wheel scripts/setup.sh pins; its `mujoco/plugin/
libsdf_plugin.so` is the plugin), e.g.

    python3 -m venv /tmp/mj317 && /tmp/mj317/bin/pip install mujoco==3.17.0
    /tmp/mj317/bin/python scripts/sdf_nutbolt.py

Three scenes, each a nut let go level over a bolt fixed upright, stepped N times (default 3000,
6 s at MuJoCo's 2 ms): the SDF nut dropped centred 10 cm over the SDF bolt's tip (MuJoCo's
default `sdf_iterations` 10 and `sdf_initpoints` 40); the same SDF nut with `radius` set for an M16
(0.0314 of the default); and the task's primitive M16 nut (six boxes round an 18 mm hexagonal
bore) dropped 2 mm over its 16 mm shank. For each: microseconds per step, contacts, and how far
the nut got down (its height over the bolt's tip at the end). One line per scene.
"""

from __future__ import annotations

import argparse
import math
import time

import mujoco

SDF = """<mujoco>
  <extension>
    <plugin plugin="mujoco.sdf.nut"><instance name="nut"><config key="radius" value="{nut_radius}"/></instance></plugin>
    <plugin plugin="mujoco.sdf.bolt"><instance name="bolt"><config key="radius" value="{bolt_radius}"/></instance></plugin>
  </extension>
  <option timestep="0.002"/>
  <asset>
    <mesh name="nut"><plugin instance="nut"/></mesh>
    <mesh name="bolt"><plugin instance="bolt"/></mesh>
  </asset>
  <worldbody>
    <body name="bolt" pos="0 0 1"><geom type="sdf" name="bolt" mesh="bolt"><plugin instance="bolt"/></geom></body>
    <body name="nut" pos="0 0 1.6"><freejoint/><geom type="sdf" name="nut" mesh="nut" density="7850"><plugin instance="nut"/></geom></body>
  </worldbody>
</mujoco>"""


def primitive_xml():
    """The task's nut (core/sim/tasks/nut_bolt_assembly.task.toml) over its shank, the shank's tip at z 0.05."""
    outer, bore = 0.012, 0.009
    walls = "".join(
        f'<geom type="box" size="{(outer - bore) / 2} {outer * math.tan(math.pi / 6)} 0.007" '
        f'pos="{(outer + bore) / 2 * math.cos(math.radians(a))} {(outer + bore) / 2 * math.sin(math.radians(a))} 0" '
        f'euler="0 0 {a}" density="7850"/>'
        for a in range(0, 360, 60))
    return f"""<mujoco><option timestep="0.002"/><worldbody>
      <geom type="box" size="0.025 0.025 0.005" pos="0 0 0.005"/>
      <geom name="shank" type="cylinder" size="0.008 0.02" pos="0 0 0.03"/>
      <body name="nut" pos="0 0 0.059"><freejoint/>{walls}</body>
    </worldbody></mujoco>"""


def run(name, xml, tip_z, nut_bottom, steps):
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    nut = model.body("nut").id
    start = time.perf_counter()
    contacts = 0
    for _ in range(steps):
        mujoco.mj_step(model, data)
        contacts += data.ncon
    per_step = (time.perf_counter() - start) / steps * 1e6
    height = data.xpos[nut][2] + nut_bottom - tip_z
    print(f"{name}: {per_step:.0f} us/step, {contacts / steps:.1f} contacts/step, the nut's bottom {height * 1000:+.1f} mm from the bolt's tip")
    return per_step


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=3000)
    args = parser.parse_args()
    # The plugin's bolt spans z -1..0 in its frame and its nut z -0.5..0 (their bounding boxes,
    # whatever `radius` says), so the bolt's tip is at its body's z and the nut's bottom 0.5 below its.
    sdf = run("SDF nut on SDF bolt (MuJoCo's example size)", SDF.format(nut_radius=0.26, bolt_radius=0.255), 1.0, -0.5, args.steps)
    run("SDF nut on SDF bolt, radius for an M16", SDF.format(nut_radius=0.26 * 0.0314, bolt_radius=0.255 * 0.0314), 1.0, -0.5, args.steps)
    prim = run("primitive M16 nut on its shank (the task's)", primitive_xml(), 0.05, -0.007, args.steps)
    print(f"SDF / primitive step time: {sdf / prim:.0f}x")


if __name__ == "__main__":
    main()
