"""Unpack the parts of a pinned wheel that this project uses (called by setup.sh).

usage: unpack_wheel.py WHEEL NAME DEST
  mujoco:    mujoco/libmujoco.so.* -> DEST/lib/ (+ the libmujoco.so link mujoco-rs looks for)
  robosuite: robosuite/models/assets/** (no bullet_data, no demonstrations) -> DEST/models/assets/
  imageio-ffmpeg: its static ffmpeg build (libx264) -> DEST/ffmpeg (encodes LeRobot videos)
"""
import os
import sys
import zipfile

wheel, name, dest = sys.argv[1:4]
with zipfile.ZipFile(wheel) as z:
    if name == "mujoco":
        lib = os.path.join(dest, "lib")
        os.makedirs(lib, exist_ok=True)
        so = [n for n in z.namelist() if n.startswith("mujoco/libmujoco.so.")]
        if len(so) != 1:
            sys.exit(f"unpack_wheel: expected one libmujoco in {wheel}, found {so}")
        target = os.path.join(lib, os.path.basename(so[0]))
        with z.open(so[0]) as src, open(target, "wb") as out:
            out.write(src.read())
        link = os.path.join(lib, "libmujoco.so")
        if os.path.lexists(link):
            os.remove(link)
        os.symlink(os.path.basename(so[0]), link)
    elif name == "robosuite":
        prefix = "robosuite/models/assets/"
        skip = (prefix + "bullet_data/", prefix + "demonstrations/")
        for n in z.namelist():
            if n.startswith(prefix) and not n.startswith(skip) and not n.endswith("/"):
                z.extract(n, dest)
    elif name == "imageio-ffmpeg":
        exe = [n for n in z.namelist() if n.startswith("imageio_ffmpeg/binaries/ffmpeg-")]
        if len(exe) != 1:
            sys.exit(f"unpack_wheel: expected one ffmpeg in {wheel}, found {exe}")
        os.makedirs(dest, exist_ok=True)
        target = os.path.join(dest, "ffmpeg")
        with z.open(exe[0]) as src, open(target, "wb") as out:
            out.write(src.read())
        os.chmod(target, 0o755)
    else:
        sys.exit(f"unpack_wheel: unknown wheel {name}")
