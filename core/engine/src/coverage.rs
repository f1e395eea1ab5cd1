//! The paper's coverage analysis (appendix "Bias and Artifacts in Generated Data"): discretise each
//! object's x, y and yaw into `n` bins and count the fraction of the `n^d` joint bins that a set of
//! scenes hits (support coverage), plus a histogram per dimension.

use std::collections::{BTreeMap, BTreeSet};

use serde::{Deserialize, Serialize};

use crate::EngineError;
use crate::pose::{Pose, yaw_of};

/// Which scalar of an object's pose a dimension measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Coordinate {
    /// World x (m).
    X,
    /// World y (m).
    Y,
    /// Rotation about world z (rad).
    Yaw,
}

/// One dimension of the coverage grid: an object's coordinate over `[low, high]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dimension {
    /// Object name.
    pub object: String,
    /// Which coordinate.
    pub coordinate: Coordinate,
    /// Lower bound of the reset region.
    pub low: f64,
    /// Upper bound of the reset region.
    pub high: f64,
}

impl Dimension {
    fn value(&self, scene: &BTreeMap<String, Pose>) -> Option<f64> {
        let pose = scene.get(&self.object)?;
        Some(match self.coordinate {
            Coordinate::X => pose.translation.x,
            Coordinate::Y => pose.translation.y,
            Coordinate::Yaw => yaw_of(pose),
        })
    }

    fn bin(&self, value: f64, bins: usize) -> usize {
        let s = ((value - self.low) / (self.high - self.low)).clamp(0.0, 1.0);
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, clippy::cast_precision_loss)]
        let b = (s * bins as f64).floor() as usize;
        b.min(bins - 1)
    }
}

/// Result of a coverage analysis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Coverage {
    /// Bins per dimension.
    pub bins: usize,
    /// The dimensions (those with an empty range are dropped).
    pub dimensions: Vec<Dimension>,
    /// Joint bins hit at least once.
    pub joint_bins_hit: usize,
    /// `bins ^ dimensions`.
    pub joint_bins_total: usize,
    /// Scene counts per bin, per dimension.
    pub histograms: Vec<Vec<usize>>,
    /// Scenes analysed.
    pub scenes: usize,
}

impl Coverage {
    /// Fraction of joint bins hit, in `[0, 1]`.
    #[must_use]
    pub fn support_coverage(&self) -> f64 {
        #[allow(clippy::cast_precision_loss)]
        if self.joint_bins_total == 0 { 0.0 } else { self.joint_bins_hit as f64 / self.joint_bins_total as f64 }
    }
}

/// Analyses `scenes` (initial object poses by name) over `dimensions` with `bins` bins each.
/// Dimensions whose range is empty (an object fixed in that coordinate) are dropped, as they cannot
/// vary. Values outside a range fall into the nearest edge bin.
///
/// # Errors
/// [`EngineError::UnknownName`] if a scene lacks a dimension's object; [`EngineError::Config`] for
/// zero bins or a grid too large to count.
pub fn coverage(scenes: &[BTreeMap<String, Pose>], dimensions: &[Dimension], bins: usize) -> Result<Coverage, EngineError> {
    if bins == 0 {
        return Err(EngineError::Config { file: String::new(), field: "bins".to_owned(), reason: "must be at least 1".to_owned() });
    }
    let dims: Vec<Dimension> = dimensions.iter().filter(|d| d.high > d.low).cloned().collect();
    let total = u32::try_from(dims.len()).ok().and_then(|n| bins.checked_pow(n)).ok_or_else(|| EngineError::Config {
        file: String::new(),
        field: "bins".to_owned(),
        reason: format!("{bins}^{} joint bins is too many", dims.len()),
    })?;
    let mut histograms = vec![vec![0usize; bins]; dims.len()];
    let mut hit = BTreeSet::new();
    for scene in scenes {
        let mut cell = Vec::with_capacity(dims.len());
        for (d, histogram) in dims.iter().zip(&mut histograms) {
            let value = d.value(scene).ok_or_else(|| EngineError::UnknownName {
                field: "coverage dimension".to_owned(),
                name: d.object.clone(),
                available: scene.keys().cloned().collect(),
            })?;
            let b = d.bin(value, bins);
            if let Some(count) = histogram.get_mut(b) {
                *count += 1;
            }
            cell.push(b);
        }
        hit.insert(cell);
    }
    Ok(Coverage { bins, dimensions: dims, joint_bins_hit: hit.len(), joint_bins_total: total, histograms, scenes: scenes.len() })
}

/// Joint bins that `scenes` scenes drawn uniformly over `joint_bins_total` bins hit on average,
/// as a fraction: `1 - (1 - 1/total)^scenes`. The reference a dataset's support coverage is read
/// against (a dataset whose scenes cluster hits fewer).
#[must_use]
pub fn uniform_support_coverage(joint_bins_total: usize, scenes: usize) -> f64 {
    if joint_bins_total == 0 {
        return 0.0;
    }
    #[allow(clippy::cast_precision_loss)]
    let miss = 1.0 - 1.0 / joint_bins_total as f64;
    1.0 - miss.powi(i32::try_from(scenes).unwrap_or(i32::MAX))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::{Rot, Vec3, pose_from_parts};

    fn scene(x: f64, y: f64, yaw: f64) -> BTreeMap<String, Pose> {
        BTreeMap::from([("cube".to_owned(), pose_from_parts(Vec3::new(x, y, 0.8), Rot::from_axis_angle(&Vec3::z_axis(), yaw)))])
    }

    fn dims() -> Vec<Dimension> {
        vec![
            Dimension { object: "cube".into(), coordinate: Coordinate::X, low: 0.0, high: 0.3 },
            Dimension { object: "cube".into(), coordinate: Coordinate::Y, low: 0.0, high: 0.3 },
            Dimension { object: "cube".into(), coordinate: Coordinate::Yaw, low: -3.0, high: 3.0 },
        ]
    }

    #[test]
    fn counts_joint_bins_and_histograms() {
        let scenes = vec![scene(0.05, 0.05, 0.0), scene(0.06, 0.04, 0.1), scene(0.25, 0.15, -2.5)];
        let c = coverage(&scenes, &dims(), 3).unwrap();
        assert_eq!(c.joint_bins_total, 27);
        assert_eq!(c.joint_bins_hit, 2);
        assert_eq!(c.histograms[0], vec![2, 0, 1]);
        assert_eq!(c.histograms[1], vec![2, 1, 0]);
        assert_eq!(c.histograms[2], vec![1, 2, 0]);
        assert!((c.support_coverage() - 2.0 / 27.0).abs() < 1e-12);
    }

    #[test]
    fn a_grid_of_scenes_covers_everything() {
        let mut scenes = Vec::new();
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    scenes.push(scene(0.05 + 0.1 * f64::from(i), 0.05 + 0.1 * f64::from(j), -2.0 + 2.0 * f64::from(k)));
                }
            }
        }
        let c = coverage(&scenes, &dims(), 3).unwrap();
        assert_eq!(c.joint_bins_hit, 27);
        assert!((c.support_coverage() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn uniform_coverage_grows_towards_one_with_scenes() {
        assert!((uniform_support_coverage(27, 1) - 1.0 / 27.0).abs() < 1e-12);
        assert!((uniform_support_coverage(1, 5) - 1.0).abs() < 1e-12);
        assert!(uniform_support_coverage(729, 1000) > 0.74 && uniform_support_coverage(729, 1000) < 0.75);
        assert!(uniform_support_coverage(729, 10) < uniform_support_coverage(729, 100));
        assert!(uniform_support_coverage(0, 10).abs() < 1e-12);
    }

    #[test]
    fn fixed_dimensions_are_dropped_and_missing_objects_named() {
        let mut d = dims();
        d[0].high = d[0].low;
        let c = coverage(&[scene(0.0, 0.1, 0.0)], &d, 3).unwrap();
        assert_eq!(c.dimensions.len(), 2);
        assert_eq!(c.joint_bins_total, 9);
        d[1].object = "peg".into();
        let err = coverage(&[scene(0.0, 0.1, 0.0)], &d, 3).unwrap_err().to_string();
        assert!(err.contains("peg"), "{err}");
    }
}
