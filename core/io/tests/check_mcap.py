"""Reads an MCAP written by `mimicgen export` with the `mcap` Python package and checks that every
channel has a JSON schema and JSON messages Foxglove can decode. Usage: check_mcap.py FILE"""
import json
import sys
from collections import Counter

from mcap.reader import make_reader

POSE_KEYS = {"timestamp", "frame_id", "pose"}
counts = Counter()
last_time = {}
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f)
    summary = reader.get_summary()
    assert summary is not None and summary.statistics.message_count > 0, "no summary/statistics"
    for schema, channel, message in reader.iter_messages():
        assert schema.encoding == "jsonschema" and channel.message_encoding == "json", channel.topic
        json.loads(schema.data)
        msg = json.loads(message.data)
        if schema.name == "foxglove.PoseInFrame":
            assert set(msg) == POSE_KEYS, msg.keys()
            q = msg["pose"]["orientation"]
            norm = sum(q[k] ** 2 for k in "xyzw")
            assert abs(norm - 1.0) < 1e-9, f"{channel.topic}: quaternion norm {norm}"
            ts = msg["timestamp"]
            assert ts["sec"] * 1_000_000_000 + ts["nsec"] == message.log_time
        else:
            assert {"timestamp", "demo", "step", "value"} <= set(msg), msg.keys()
        assert message.log_time >= last_time.get(channel.topic, 0), f"{channel.topic}: time goes back"
        last_time[channel.topic] = message.log_time
        counts[channel.topic] += 1
for topic in ("/eef_pose", "/target_pose", "/actions", "/gripper", "/subtask", "/source_demo", "/success"):
    assert counts[topic] > 0, f"no messages on {topic}"
print("ok:", dict(counts))
