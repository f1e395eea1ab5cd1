"""Walks an HDF5 dataset the way robomimic's SequenceDataset loader does and fails on anything it
would trip over. Usage: check_robomimic_layout.py FILE [FILTER_KEY]

Mirrors robomimic 0.3 `robomimic/utils/file_utils.py` (get_env_metadata_from_dataset,
get_shape_metadata_from_dataset) and `robomimic/utils/dataset.py` (SequenceDataset.load_demo_info,
load_dataset_in_memory): env_args is JSON with env_name/type/env_kwargs, demos are sorted by their
integer suffix, each demo's num_samples attribute gives its length, actions and obs/<key> are read
per demo, filter keys under mask/ are byte strings of demo names.
"""
import json
import sys

import h5py
import numpy as np

path = sys.argv[1]
filter_key = sys.argv[2] if len(sys.argv) > 2 else None

with h5py.File(path, "r") as f:
    # get_env_metadata_from_dataset
    env_meta = json.loads(f["data"].attrs["env_args"])
    for k in ("env_name", "type", "env_kwargs"):
        assert k in env_meta, f"env_args lacks {k}"
    # load_demo_info
    if filter_key is not None:
        demos = [elem.decode("utf-8") for elem in np.array(f["mask/{}".format(filter_key)][:])]
    else:
        demos = list(f["data"].keys())
    inds = np.argsort([int(elem[5:]) for elem in demos])
    demos = [demos[i] for i in inds]
    total = 0
    obs_shapes = None
    for ep in demos:
        demo = f["data/{}".format(ep)]
        n = demo.attrs["num_samples"]
        assert isinstance(n, (int, np.integer)) and n > 0, f"{ep}: num_samples {n!r}"
        total += int(n)
        actions = demo["actions"][()]
        assert actions.dtype == np.float64 and actions.ndim == 2 and actions.shape[0] == n, f"{ep}: actions {actions.dtype}{actions.shape}"
        for key in ("rewards", "dones"):
            if key in demo:
                assert demo[key].shape == (n,), f"{ep}/{key}: {demo[key].shape}"
        # get_shape_metadata_from_dataset reads demo_0's obs; load_dataset_in_memory reads every key of every demo
        assert "obs" in demo, f"{ep}: no obs group (robomimic's SequenceDataset needs observations)"
        shapes = {k: demo["obs/{}".format(k)].shape[1:] for k in demo["obs"]}
        for k in demo["obs"]:
            v = demo["obs/{}".format(k)][()]
            assert v.shape[0] == n and v.dtype in (np.float32, np.float64, np.uint8), f"{ep}/obs/{k}: {v.dtype}{v.shape}"
        assert obs_shapes in (None, shapes), f"{ep}: obs shapes {shapes} differ from {obs_shapes}"
        obs_shapes = shapes
        if "states" in demo:
            assert demo["states"].shape[0] == n
        if "datagen_info" in demo:
            assert demo["datagen_info/eef_pose"].shape == (n, 4, 4)
        if "src_demo_labels" in demo:
            assert demo["src_demo_labels"].shape == (n, 1)
        assert "model_file" not in demo.attrs or isinstance(demo.attrs["model_file"], str)
    if filter_key is None:
        assert int(f["data"].attrs["total"]) == total, f"total {f['data'].attrs['total']} != {total}"
    for key in f.get("mask", {}):
        names = [e.decode("utf-8") for e in np.array(f["mask/" + key][:])]
        assert all(n in f["data"] for n in names), f"mask/{key} names unknown demos"
print(f"ok: {len(demos)} demos, {total} samples, obs {obs_shapes}")
