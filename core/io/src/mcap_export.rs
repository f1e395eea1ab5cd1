//! Exports a dataset's streams to MCAP with JSON messages and JSON schemas that Foxglove reads:
//! poses as `foxglove.PoseInFrame`, everything else as small `mimicgen.*` records. One step is
//! 50 ms of log time (20 Hz, robosuite's control rate); demos follow one another.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use mcap::records::MessageHeader;
use serde::Serialize;
use serde_json::{Value, json};

use crate::dataset::{DemoSource, demo_steps};
use crate::error::{IoError, Result};
use crate::info::first_transition;
use crate::tree::{Dataset, Group, Node};

/// Log time between steps (20 Hz).
pub const STEP_NANOS: u64 = 50_000_000;

/// What an export wrote.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct ExportSummary {
    /// Demos exported.
    pub demos: usize,
    /// Steps exported.
    pub steps: u64,
    /// Messages per topic.
    pub messages: BTreeMap<String, u64>,
}

/// JSON schema of `foxglove.PoseInFrame`.
#[must_use]
pub fn pose_in_frame_schema() -> Value {
    let num = json!({"type": "number"});
    let xyz = json!({"type": "object", "properties": {"x": num, "y": num, "z": num}});
    let xyzw = json!({"type": "object", "properties": {"x": num, "y": num, "z": num, "w": num}});
    json!({
        "title": "foxglove.PoseInFrame",
        "description": "A timestamped pose for an object or reference frame in 3D space",
        "type": "object",
        "properties": {
            "timestamp": {"type": "object", "title": "time", "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}},
            "frame_id": {"type": "string"},
            "pose": {"type": "object", "title": "foxglove.Pose", "properties": {"position": xyz, "orientation": xyzw}}
        }
    })
}

fn record_schema(title: &str, value: &Value) -> Value {
    json!({
        "title": title,
        "type": "object",
        "properties": {
            "timestamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
            "demo": {"type": "string"},
            "step": {"type": "integer"},
            "value": value
        }
    })
}

struct Out {
    writer: mcap::Writer<BufWriter<File>>,
    file: String,
    channels: BTreeMap<String, u16>,
    schemas: BTreeMap<String, u16>,
    sequence: u32,
    summary: ExportSummary,
}

impl Out {
    fn err(&self, channel: &str, e: &mcap::McapError) -> IoError {
        IoError::Mcap { file: self.file.clone(), channel: channel.to_owned(), reason: e.to_string() }
    }

    fn channel(&mut self, topic: &str, schema_name: &str, schema: &Value) -> Result<u16> {
        if let Some(&id) = self.channels.get(topic) {
            return Ok(id);
        }
        let schema_id = match self.schemas.get(schema_name) {
            Some(&id) => id,
            None => {
                let id =
                    self.writer.add_schema(schema_name, "jsonschema", schema.to_string().as_bytes()).map_err(|e| self.err(topic, &e))?;
                self.schemas.insert(schema_name.to_owned(), id);
                id
            }
        };
        let id = self.writer.add_channel(schema_id, topic, "json", &BTreeMap::new()).map_err(|e| self.err(topic, &e))?;
        self.channels.insert(topic.to_owned(), id);
        Ok(id)
    }

    fn write(&mut self, topic: &str, schema_name: &str, schema: &Value, log_time: u64, msg: &Value) -> Result<()> {
        let channel_id = self.channel(topic, schema_name, schema)?;
        self.sequence = self.sequence.wrapping_add(1);
        let header = MessageHeader { channel_id, sequence: self.sequence, log_time, publish_time: log_time };
        self.writer.write_to_known_channel(&header, msg.to_string().as_bytes()).map_err(|e| self.err(topic, &e))?;
        *self.summary.messages.entry(topic.to_owned()).or_default() += 1;
        Ok(())
    }
}

fn stamp(log_time: u64) -> Value {
    json!({"sec": log_time / 1_000_000_000, "nsec": log_time % 1_000_000_000})
}

fn pose_msg(log_time: u64, m: &[f64; 16]) -> Value {
    let rot = quat_xyzw_of([[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]]);
    json!({
        "timestamp": stamp(log_time),
        "frame_id": "world",
        "pose": {"position": {"x": m[3], "y": m[7], "z": m[11]}, "orientation": {"x": rot[0], "y": rot[1], "z": rot[2], "w": rot[3]}}
    })
}

/// Quaternion `[x, y, z, w]` of a rotation matrix (Shepperd's method), without re-validating it.
fn quat_xyzw_of(r: [[f64; 3]; 3]) -> [f64; 4] {
    let m = mimicgen_engine::pose::Mat4::new(
        r[0][0], r[0][1], r[0][2], 0.0, r[1][0], r[1][1], r[1][2], 0.0, r[2][0], r[2][1], r[2][2], 0.0, 0.0, 0.0, 0.0, 1.0,
    );
    match mimicgen_engine::pose::pose_from_matrix(&m, "") {
        Ok(p) => {
            // Renormalise: a rotation that is orthonormal only to 1e-5 gives a quaternion that is unit only to 1e-9.
            let q = mimicgen_engine::pose::quat_to_xyzw(&p.rotation);
            let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            q.map(|v| v / n)
        }
        Err(_) => [f64::NAN; 4], // exported as-is; the reader flags bad poses elsewhere
    }
}

fn floats(d: Option<&Dataset>) -> Option<(Vec<f64>, usize)> {
    let d = d?;
    let width = d.array.shape.get(1..).map_or(1, |s| s.iter().product());
    Some((d.array.values.to_f64()?, width.max(1)))
}

/// Writes every demo's streams to `out`.
///
/// # Errors
/// [`IoError::Fs`] when `out` cannot be created, [`IoError::Mcap`] on write errors, read errors
/// of [`DemoSource::load_demo`].
pub fn export(ds: &impl DemoSource, out: impl AsRef<Path>) -> Result<ExportSummary> {
    let file = out.as_ref().display().to_string();
    let f = File::create(out.as_ref()).map_err(|e| IoError::Fs { file: file.clone(), reason: e.to_string() })?;
    let writer = mcap::Writer::new(BufWriter::new(f)).map_err(|e| IoError::Mcap {
        file: file.clone(),
        channel: String::new(),
        reason: e.to_string(),
    })?;
    let mut out = Out { writer, file, channels: BTreeMap::new(), schemas: BTreeMap::new(), sequence: 0, summary: ExportSummary::default() };
    let pose_schema = pose_in_frame_schema();
    let vector = record_schema("mimicgen.Vector", &json!({"type": "array", "items": {"type": "number"}}));
    let label = record_schema("mimicgen.Label", &json!({"type": "integer"}));
    let success = record_schema("mimicgen.Success", &json!({"type": ["boolean", "null"]}));
    let mut step0 = 0_u64;
    for name in ds.demo_names() {
        let demo = ds.load_demo(name)?;
        let demo: &Group = &demo;
        let steps = demo_steps(demo);
        let info = demo.group("datagen_info");
        let mut pose_streams: Vec<(String, Vec<f64>)> = Vec::new();
        if let Some(info) = info {
            for (field, topic) in [("eef_pose", "/eef_pose"), ("target_pose", "/target_pose")] {
                if let Some((v, _)) = floats(info.dataset(field)) {
                    pose_streams.push((topic.to_owned(), v));
                }
            }
            if let Some(objects) = info.group("object_poses") {
                for (obj, node) in &objects.members {
                    if let Node::Dataset(d) = node
                        && let Some((v, _)) = floats(Some(d))
                    {
                        pose_streams.push((format!("/objects/{obj}"), v));
                    }
                }
            }
        }
        let actions = floats(demo.dataset("actions"));
        let gripper = info.and_then(|i| floats(i.dataset("gripper_action")));
        let src_labels = demo.dataset("src_demo_labels").and_then(|d| d.array.values.to_i64());
        let subtask = subtask_labels(info, steps);
        for t in 0..steps {
            let log_time = (step0 + t as u64) * STEP_NANOS;
            for (topic, v) in &pose_streams {
                if let Some(m) = v.get(t * 16..t * 16 + 16).and_then(|m| <&[f64; 16]>::try_from(m).ok()) {
                    out.write(topic, "foxglove.PoseInFrame", &pose_schema, log_time, &pose_msg(log_time, m))?;
                }
            }
            let record = |value: Value| json!({"timestamp": stamp(log_time), "demo": name, "step": t, "value": value});
            for (topic, stream) in [("/actions", &actions), ("/gripper", &gripper)] {
                if let Some((v, w)) = stream
                    && let Some(row) = v.get(t * w..(t + 1) * w)
                {
                    out.write(topic, "mimicgen.Vector", &vector, log_time, &record(json!(row)))?;
                }
            }
            if let Some(k) = subtask.as_ref().and_then(|s| s.get(t)) {
                out.write("/subtask", "mimicgen.Label", &label, log_time, &record(json!(k)))?;
            }
            if let Some(v) = src_labels.as_ref().and_then(|v| v.get(t)) {
                out.write("/source_demo", "mimicgen.Label", &label, log_time, &record(json!(v)))?;
            }
        }
        if steps > 0 {
            let log_time = (step0 + steps as u64 - 1) * STEP_NANOS;
            let ok = demo_success(demo);
            out.write(
                "/success",
                "mimicgen.Success",
                &success,
                log_time,
                &json!({"timestamp": stamp(log_time), "demo": name, "step": steps - 1, "value": ok}),
            )?;
        }
        step0 += steps as u64;
        out.summary.demos += 1;
    }
    out.summary.steps = step0;
    let file = out.file.clone();
    out.writer.finish().map_err(|e| IoError::Mcap { file: file.clone(), channel: String::new(), reason: e.to_string() })?;
    Ok(out.summary)
}

/// Subtask index per step: how many subtask signals have had their first 0 -> 1 transition at or
/// before the step (MimicGen's subtasks end on these transitions, in order).
fn subtask_labels(info: Option<&Group>, steps: usize) -> Option<Vec<usize>> {
    let signals = info?.group("subtask_term_signals")?;
    let firsts: Vec<usize> = signals
        .members
        .values()
        .filter_map(|n| match n {
            Node::Dataset(d) => d.array.values.to_i64().as_deref().and_then(first_transition),
            Node::Group(_) => None,
        })
        .collect();
    Some((0..steps).map(|t| firsts.iter().filter(|&&f| f <= t).count()).collect())
}

/// Success of a demo from its rewards or dones; `None` when the file records neither.
fn demo_success(demo: &Group) -> Option<bool> {
    let any_on = |field: &str| demo.dataset(field).and_then(|d| d.array.values.to_f64()).map(|v| v.iter().any(|&x| x > 0.0));
    any_on("rewards").or_else(|| any_on("dones"))
}
