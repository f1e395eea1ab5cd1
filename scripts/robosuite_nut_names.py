#!/usr/bin/env python3
"""Rename the nuts' visual geoms in a dataset's model_file as robosuite names them (`_visual`) and
add robosuite's `default_site` to each nut, in every demo of the files given, in place.

robosuite 1.4.1's NutAssembly environments look both up when they load a model_file; neither
changes the physics (visual geoms do not collide, a site has no mass). `mimicgen demos` writes
them since session 13; this brought the bundled Square and Nut Assembly source demos (recorded
before) up to date without re-recording them:

    python3 scripts/robosuite_nut_names.py core/sim/data/square_D0_source.hdf5 core/sim/data/nut_assembly_D0_source.hdf5
"""
import re
import sys

import h5py

VISUAL = re.compile(r'name="((?:Square|Round)Nut_g\d+)_vis"')
RADIUS_SITE = re.compile(r'<site name="((?:Square|Round)Nut)_horizontal_radius_site"[^>]*/>')


def with_default_site(match):
    nut = match.group(1)
    return match.group(0) + f'\n      <site name="{nut}_default_site" pos="0 0 0" size="0.002" rgba="1 0 0 0"/>'


def patched(xml):
    """The model_file with robosuite's names, and how many names and sites changed."""
    xml, renamed = VISUAL.subn(r'name="\1_visual"', xml)
    added = 0
    if "Nut_default_site" not in xml:
        xml, added = RADIUS_SITE.subn(with_default_site, xml)
    return xml, renamed + added


for path in sys.argv[1:]:
    with h5py.File(path, "r+") as f:
        changed = 0
        for demo in f["data"].values():
            xml = demo.attrs["model_file"]
            xml, n = patched(xml.decode() if isinstance(xml, bytes) else xml)
            if n:
                demo.attrs["model_file"] = xml
                changed += n
        print(f"{path}: {changed} names and sites")
