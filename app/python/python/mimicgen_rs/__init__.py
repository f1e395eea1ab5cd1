"""MimicGen data generation from Python, on the Rust pipeline behind the ``mimicgen`` CLI.

Read datasets, load and edit task specs, propose and write subtask ends, generate (on the
bundled MuJoCo backend, or on your own simulator), measure coverage, and join shards::

    import mimicgen_rs as mg

    run = mg.generate("out/stack.hdf5", num_demos=20, seed=1, workers=2)
    for event in run:                       # events as the run goes
        if event["kind"] == "attempt":
            print(event["index"], event["success"], event["stats"]["successes"])
    print(run.report["generation_rate"])    # or: report = run.wait()

    ds = mg.Dataset("out/stack.hdf5")
    info = ds.datagen_info(ds.demo_names[0])  # eef_pose (T, 4, 4), object_poses, signals...

Long calls release the GIL. Ctrl-C during a run stops it after the attempts already decided
and leaves a valid (partial) dataset; the report then says ``cancelled``. Errors are
``MimicgenError`` with the CLI's message, naming the file and field at fault.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import threading
from typing import Any, Dict, Iterable, Iterator, List, Mapping, Optional, Protocol, Sequence, Tuple, Union

import numpy as np

from . import _native
from ._native import Dataset, MimicgenError, Spec
from .env import Env

__all__ = [
    "Dataset",
    "Env",
    "Environment",
    "MimicgenError",
    "Run",
    "Spec",
    "coverage",
    "export_lerobot",
    "generate",
    "merge",
    "propose_subtask_ends",
    "tasks",
    "write_subtask_ends",
]
__version__ = _native.__version__

PathLike = Union[str, "os.PathLike[str]"]

#: Spec fields a run may set over its spec's, as `mimicgen generate` takes them.
SPEC_FIELDS = ("selection", "nn_k", "action_noise", "offset_range", "interpolation_steps", "fixed_steps", "transit", "approach_m")


class Environment(Protocol):
    """What the engine asks of a simulator you bring (``generate(..., env=factory)``).

    Poses are 4x4 homogeneous matrices (``world_from_frame``), actions are arrays of
    ``action_dim()`` numbers (six pose dimensions, then the gripper). The engine resets, reads
    the end effector, objects and signals, converts target poses to actions, steps, and keeps
    states to replay; your environment owns its own random numbers, seeded by ``reset``.
    """

    def action_dim(self) -> int: ...
    def reset(self, seed: int) -> None: ...
    def eef_pose(self) -> np.ndarray: ...
    def object_poses(self) -> Dict[str, np.ndarray]: ...
    def subtask_term_signals(self) -> Dict[str, int]: ...
    def is_success(self) -> bool: ...
    def target_pose_to_action(self, target_pose: np.ndarray) -> Sequence[float]: ...
    def action_to_target_pose(self, action: np.ndarray) -> np.ndarray: ...
    def step(self, action: np.ndarray) -> None: ...
    def get_state(self) -> np.ndarray: ...
    def set_state(self, state: np.ndarray) -> None: ...
    # Optional: place_objects(poses: dict) for scenes set by hand, and observations() -> dict of
    # arrays, called after set_state on every stored state of a kept attempt.


def _path(p: Optional[PathLike]) -> Optional[str]:
    return None if p is None else os.fspath(p)


def _scoped(field: str, value: Any) -> List[Dict[str, Any]]:
    """``0.02`` (every subtask) or ``{1: 0.02}`` (subtask 1) as the pipeline's scoped values."""
    def one(v: Any) -> Any:
        if field == "offset_range":
            lo, hi = v
            return [int(lo), int(hi)]
        return v

    if isinstance(value, Mapping):
        return [{"subtask": int(k), "value": one(v)} for k, v in value.items()]
    return [{"subtask": None, "value": one(value)}]


def _spec_overrides(spec: Optional[Mapping[str, Any]]) -> Dict[str, Any]:
    out: Dict[str, Any] = {}
    for key, value in (spec or {}).items():
        if key == "select_src_per_subtask":
            out[key] = bool(value)
        elif key == "exclude_source":
            out[key] = [int(d) for d in ([value] if isinstance(value, int) else value)]
        elif key in SPEC_FIELDS:
            out[key] = _scoped(key, value)
        else:
            raise MimicgenError(f"spec: unknown field {key!r}; known: {', '.join(SPEC_FIELDS + ('select_src_per_subtask', 'exclude_source'))}")
    return out


def _shard(shard: Union[None, str, Tuple[int, int]]) -> Optional[Dict[str, int]]:
    if shard is None:
        return None
    if isinstance(shard, str):
        part, _, count = shard.partition("/")
        shard = (int(part), int(count))
    part, count = shard
    if not 0 <= part < count:
        raise MimicgenError(f"shard {part}/{count} does not exist: the shards of K are 0/K to {count - 1}/K")
    return {"part": int(part), "count": int(count)}


@contextlib.contextmanager
def _cancel_on_sigint(native: Any) -> Iterator[None]:
    """While the body runs on the main thread, Ctrl-C first cancels ``native`` (so the run
    finishes its outputs as valid datasets wherever the KeyboardInterrupt surfaces), then raises
    as it would have."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.getsignal(signal.SIGINT)

    def on_sigint(signum: int, frame: Any) -> None:
        native.cancel()
        if callable(previous):
            previous(signum, frame)
        else:
            raise KeyboardInterrupt

    signal.signal(signal.SIGINT, on_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


class Run:
    """A generation run going on in the background: iterate it for events (dicts with ``kind``
    ``started`` or ``attempt``), ``wait()`` for the report, ``cancel()``. Ctrl-C while iterating or
    waiting cancels the run, whose outputs are finished as valid datasets (``report["cancelled"]``),
    and raises ``KeyboardInterrupt``."""

    def __init__(self, native: Any) -> None:
        self._native = native

    def __iter__(self) -> Iterator[Dict[str, Any]]:
        with _cancel_on_sigint(self._native):
            yield from self._native

    def wait(self) -> Dict[str, Any]:
        """Waits for the end and returns the report."""
        with _cancel_on_sigint(self._native):
            return self._native.wait()

    def cancel(self) -> None:
        """Stops after the attempts already decided; the outputs are finished as valid datasets."""
        self._native.cancel()

    @property
    def report(self) -> Optional[Dict[str, Any]]:
        """The report once the run has ended (``None`` before; after a cancel, the cancelled run's)."""
        return self._native.report


def _cameras(
    cameras: Union[None, bool, Sequence[str]], size: Union[int, Tuple[int, int]], depth: bool, fast: bool
) -> Optional[Dict[str, Any]]:
    if cameras is None or cameras is False:
        return None
    names = ["agentview", "robot0_eye_in_hand"] if cameras is True else [str(c) for c in cameras]
    height, width = (size, size) if isinstance(size, int) else (int(size[0]), int(size[1]))
    return {"names": names, "height": int(height), "width": int(width), "depth": bool(depth), "fast": bool(fast)}


def generate(
    out: PathLike,
    *,
    task: Optional[str] = None,
    variant: Optional[str] = None,
    robot: Optional[str] = None,
    source: Optional[PathLike] = None,
    config: Optional[PathLike] = None,
    num_demos: Optional[int] = None,
    seed: Optional[int] = None,
    workers: int = 1,
    keep_failed: bool = False,
    guarantee: bool = False,
    max_attempts: Optional[int] = None,
    valid_fraction: Optional[float] = None,
    early_abort: bool = False,
    overwrite: bool = False,
    resume: bool = False,
    shard: Union[None, str, Tuple[int, int]] = None,
    spec: Optional[Mapping[str, Any]] = None,
    cameras: Union[None, bool, Sequence[str]] = None,
    camera_size: Union[int, Tuple[int, int]] = 84,
    camera_depth: bool = False,
    camera_fast: bool = False,
    actions: Sequence[str] = (),
    env: Optional[Any] = None,
) -> Run:
    """Start a generation run in the background; the arguments are ``mimicgen generate``'s.

    ``spec`` sets spec fields for this run: ``{"action_noise": 0.02, "nn_k": {1: 5},
    "selection": "nearest_neighbor_object", "offset_range": (0, 10)}`` (a value for every
    subtask, or a dict by subtask index). ``shard="0/4"`` makes share 0 of 4 (join them with
    :func:`merge`). ``robot="sawyer"`` (or ``"iiwa"``) generates with that arm from the same
    source demos. ``cameras=True`` renders agentview and the wrist camera into every kept demo
    (``obs/<camera>_image``, uint8), or name them: ``cameras=["agentview", "frontview"]``, at
    ``camera_size`` (``84`` or ``(height, width)``); ``camera_depth`` adds depth, ``camera_fast``
    renders without multisampling (faster, edges differ from robosuite's). ``env`` is a callable
    returning an :class:`Environment` (one per worker) to drive instead of the bundled MuJoCo
    backend. ``actions=["abs"]`` also writes ``actions_abs`` in every demo (the controller's
    absolute target: position, axis-angle rotation, gripper; robomimic's convention);
    ``"joint"`` writes ``actions_joint`` (the arm's joint positions at the next step, gripper).

    Returns a :class:`Run`: iterate it for events, ``wait()`` for the report, ``cancel()``.
    """
    cfg = {
        "task": task,
        "variant": variant,
        "robot": robot,
        "config": _path(config),
        "source": _path(source),
        "out": os.fspath(out),
        "workers": int(workers),
        "num_demos": num_demos,
        "seed": seed,
        "keep_failed": keep_failed,
        "guarantee": guarantee,
        "max_attempts": max_attempts,
        "valid_fraction": valid_fraction,
        "early_abort": early_abort,
        "overwrite": overwrite,
        "resume": resume,
        "spec": _spec_overrides(spec),
        "shard": _shard(shard),
        "cameras": _cameras(cameras, camera_size, camera_depth, camera_fast),
        "actions": [str(a) for a in ([actions] if isinstance(actions, str) else actions)],
    }
    if env is not None and not callable(env):
        raise MimicgenError("env: pass a callable that returns a new environment (one per worker), e.g. a class")
    return Run(_native.generate(json.dumps(cfg), env))


def propose_subtask_ends(path: PathLike, task: Optional[str] = None, config: Optional[PathLike] = None) -> Dict[str, List[Dict[str, Any]]]:
    """Proposed subtask ends of every demo: ``{demo: [{"end", "confidence", "reason"}, ...]}``."""
    return json.loads(_native.propose_subtask_ends(os.fspath(path), task, _path(config)))


def write_subtask_ends(
    source: PathLike,
    out: PathLike,
    ends: Mapping[str, Iterable[int]],
    task: Optional[str] = None,
    config: Optional[PathLike] = None,
) -> None:
    """Write ``source`` to ``out`` with the subtask ends ``{demo: [end, ...]}`` (exclusive, one per
    subtask but the last) as the signals MimicGen reads."""
    as_json = json.dumps({str(k): [int(e) for e in v] for k, v in ends.items()})
    _native.write_subtask_ends(os.fspath(source), os.fspath(out), as_json, task, _path(config))


def tasks() -> Dict[str, List[Dict[str, Any]]]:
    """Every task (``name``, robosuite ``env_name``, ``variants``, ``description``, ``instruction``,
    ``objects``, ``signals``) and every arm (``name``, ``robosuite_name``, ``status``), as
    ``mimicgen tasks`` lists them; task files under ``$MIMICGEN_TASK_DIR`` included. A task file
    that does not parse is under ``broken`` (``name``, ``error``); the other tasks still work."""
    return json.loads(_native.tasks())


def coverage(path: PathLike, task: Optional[str] = None, variant: Optional[str] = None, bins: int = 3) -> Dict[str, Any]:
    """The paper's support coverage of a dataset's initial scenes (``mimicgen coverage --json``)."""
    return json.loads(_native.coverage(os.fspath(path), task, variant, int(bins)))


def merge(shards: Sequence[PathLike], out: PathLike, overwrite: bool = False) -> Dict[str, Any]:
    """Join the shards of a run (``generate(..., shard="i/K")``) into the whole run's dataset;
    returns its report."""
    return json.loads(_native.merge([os.fspath(s) for s in shards], os.fspath(out), overwrite))


def export_lerobot(
    path: PathLike,
    out: PathLike,
    *,
    state_keys: Optional[Sequence[str]] = None,
    instruction: Optional[str] = None,
    ffmpeg: Optional[PathLike] = None,
    overwrite: bool = False,
) -> Dict[str, Any]:
    """Export a dataset as a LeRobot dataset (format v3.0; ``mimicgen export --lerobot``): parquet
    frames, camera streams as H.264 videos, ``meta/``. Returns what was written."""
    keys = None if state_keys is None else [str(k) for k in state_keys]
    return json.loads(_native.export_lerobot(os.fspath(path), os.fspath(out), keys, instruction, _path(ffmpeg), overwrite))
