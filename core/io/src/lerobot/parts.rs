//! The running parts of an export: where the current parquet and video files are
//! (`chunk-NNN/file-NNN`), and each feature's statistics (`meta/stats.json`).

use serde_json::{Value, json};

use super::CHUNK_SIZE;

/// Where an episode's frames live: `(chunk, file)` indices.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) struct FileSlot {
    pub(super) chunk: usize,
    pub(super) file: usize,
}

impl FileSlot {
    pub(super) fn next(self) -> Self {
        if self.file + 1 >= CHUNK_SIZE { Self { chunk: self.chunk + 1, file: 0 } } else { Self { chunk: self.chunk, file: self.file + 1 } }
    }

    pub(super) fn path(self, dir: &str, ext: &str) -> String {
        format!("{dir}/chunk-{:03}/file-{:03}.{ext}", self.chunk, self.file)
    }
}

/// Running per-dimension statistics (LeRobot's `min`, `max`, `mean`, `std`, `count`).
#[derive(Debug, Clone, Default)]
pub(super) struct Stats {
    min: Vec<f64>,
    max: Vec<f64>,
    sum: Vec<f64>,
    sum_sq: Vec<f64>,
    count: u64,
}

impl Stats {
    pub(super) fn add(&mut self, row: &[f64]) {
        if self.min.is_empty() {
            self.min = vec![f64::INFINITY; row.len()];
            self.max = vec![f64::NEG_INFINITY; row.len()];
            self.sum = vec![0.0; row.len()];
            self.sum_sq = vec![0.0; row.len()];
        }
        let columns = self.min.iter_mut().zip(self.max.iter_mut()).zip(self.sum.iter_mut().zip(self.sum_sq.iter_mut()));
        for (((min, max), (sum, sum_sq)), &v) in columns.zip(row) {
            *min = min.min(v);
            *max = max.max(v);
            *sum += v;
            *sum_sq += v * v;
        }
        self.count += 1;
    }

    /// As LeRobot's `stats.json` has it; `image` nests each value as `[[v]]` (per channel, `(3, 1, 1)`).
    #[allow(clippy::cast_precision_loss)]
    pub(super) fn to_json(&self, image: bool) -> Value {
        let n = self.count.max(1) as f64;
        let mean: Vec<f64> = self.sum.iter().map(|s| s / n).collect();
        let std: Vec<f64> = self.sum_sq.iter().zip(&mean).map(|(sq, m)| (sq / n - m * m).max(0.0).sqrt()).collect();
        let shape = |v: &[f64]| if image { json!(v.iter().map(|x| json!([[x]])).collect::<Vec<_>>()) } else { json!(v) };
        json!({"min": shape(&self.min), "max": shape(&self.max), "mean": shape(&mean), "std": shape(&std), "count": [self.count]})
    }
}
