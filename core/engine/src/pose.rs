//! Rigid poses, named by their frames (`world_from_eef`), and the conversions MimicGen files need.
//!
//! Every pose is an [`Isometry3<f64>`]: a rotation followed by a translation, SI units, radians.
//! Quaternion order is spelled out at every boundary: [`quat_from_wxyz`] / [`quat_to_wxyz`] for
//! MuJoCo and MimicGen's pose utilities, [`quat_from_xyzw`] / [`quat_to_xyzw`] for robosuite's
//! observations (`robot0_eef_quat`).

use nalgebra::{Isometry3, Matrix3, Matrix4, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::EngineError;

/// A rigid transform `a_from_b`: maps coordinates in frame `b` to frame `a`.
pub type Pose = Isometry3<f64>;
/// A unit quaternion rotation.
pub type Rot = UnitQuaternion<f64>;
/// A 3-vector (position, axis-angle, velocity).
pub type Vec3 = Vector3<f64>;
/// The homogeneous 4x4 matrix MimicGen stores for poses.
pub type Mat4 = Matrix4<f64>;

/// Tolerance on `R^T R - I` and on the bottom row for a matrix to count as a rigid transform.
pub const RIGID_TOLERANCE: f64 = 1e-5;

/// Builds a pose from a position and a rotation.
#[must_use]
pub fn pose_from_parts(position: Vec3, rotation: Rot) -> Pose {
    Isometry3::from_parts(Translation3::from(position), rotation)
}

/// Returns the homogeneous 4x4 matrix of `pose`.
#[must_use]
pub fn pose_to_matrix(pose: &Pose) -> Mat4 {
    pose.to_homogeneous()
}

/// Reads a rigid transform from a 4x4 matrix, rejecting NaN, non-orthonormal rotations and a bad
/// bottom row. `what` names the source in the error (e.g. `demo_3/datagen_info/eef_pose[17]`).
///
/// The rotation part is re-orthonormalised through a quaternion, so `pose_to_matrix` of the result
/// equals the input to within [`RIGID_TOLERANCE`].
///
/// # Errors
/// [`EngineError::InvalidPose`] when the matrix is not a finite rigid transform.
pub fn pose_from_matrix(m: &Mat4, what: &str) -> Result<Pose, EngineError> {
    let invalid = |reason: String| EngineError::InvalidPose { what: what.to_owned(), reason };
    if m.iter().any(|v| !v.is_finite()) {
        return Err(invalid("contains NaN or infinity".to_owned()));
    }
    let bottom = [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)] - 1.0];
    if bottom.iter().any(|v| v.abs() > RIGID_TOLERANCE) {
        return Err(invalid(format!("bottom row is {:?}, expected [0, 0, 0, 1]", [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]])));
    }
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let orthonormal_error = (r.transpose() * r - Matrix3::identity()).abs().max();
    if orthonormal_error > RIGID_TOLERANCE {
        return Err(invalid(format!("rotation is not orthonormal (|R^T R - I| = {orthonormal_error:.2e})")));
    }
    if r.determinant() < 0.0 {
        return Err(invalid("rotation is a reflection (det < 0)".to_owned()));
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(pose_from_parts(Vec3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]), rotation))
}

/// Quaternion from `[w, x, y, z]` (MuJoCo, MimicGen pose utilities). Normalises the input.
#[must_use]
pub fn quat_from_wxyz(q: [f64; 4]) -> Rot {
    UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
}

/// Quaternion to `[w, x, y, z]`.
#[must_use]
pub fn quat_to_wxyz(q: &Rot) -> [f64; 4] {
    [q.w, q.i, q.j, q.k]
}

/// Quaternion from `[x, y, z, w]` (robosuite observations). Normalises the input.
#[must_use]
pub fn quat_from_xyzw(q: [f64; 4]) -> Rot {
    UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
}

/// Quaternion to `[x, y, z, w]`.
#[must_use]
pub fn quat_to_xyzw(q: &Rot) -> [f64; 4] {
    [q.i, q.j, q.k, q.w]
}

/// Rotation from an axis-angle vector (direction = axis, norm = angle in radians).
#[must_use]
pub fn rot_from_axis_angle(axis_angle: &Vec3) -> Rot {
    UnitQuaternion::from_scaled_axis(*axis_angle)
}

/// Axis-angle vector of a rotation, with the angle in `[0, pi]`.
#[must_use]
pub fn rot_to_axis_angle(rotation: &Rot) -> Vec3 {
    rotation.scaled_axis()
}

/// Weights of the pose distance used for nearest-neighbour selection.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PoseDistanceWeights {
    /// Weight on the position distance (per metre).
    pub position: f64,
    /// Weight on the rotation angle (per radian).
    pub rotation: f64,
}

impl Default for PoseDistanceWeights {
    fn default() -> Self {
        Self { position: 1.0, rotation: 1.0 }
    }
}

/// The paper's pose distance: weighted L2 position distance plus weighted angle of the relative
/// rotation (radians, in `[0, pi]`).
#[must_use]
pub fn pose_distance(a: &Pose, b: &Pose, weights: PoseDistanceWeights) -> f64 {
    let position = (a.translation.vector - b.translation.vector).norm();
    let angle = a.rotation.angle_to(&b.rotation);
    weights.position * position + weights.rotation * angle
}

/// Yaw (rotation about world +z, radians in `(-pi, pi]`) of a pose's x axis projected on the
/// ground plane. Used by coverage analysis of table-top scenes.
#[must_use]
pub fn yaw_of(pose: &Pose) -> f64 {
    let x_axis = pose.rotation * Vec3::x();
    x_axis.y.atan2(x_axis.x)
}

/// Checks that a pose is finite; `what` names it in the error.
///
/// # Errors
/// [`EngineError::InvalidPose`] when any component is NaN or infinite.
pub fn check_finite(pose: &Pose, what: &str) -> Result<(), EngineError> {
    let finite = pose.translation.vector.iter().all(|v| v.is_finite()) && pose.rotation.coords.iter().all(|v| v.is_finite());
    if finite { Ok(()) } else { Err(EngineError::InvalidPose { what: what.to_owned(), reason: "contains NaN or infinity".to_owned() }) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(clippy::float_cmp)] // these conversions only move exact values around
    fn quaternion_orders_are_not_confused() {
        let q = quat_from_wxyz([0.5, 0.5, 0.5, 0.5]);
        assert_eq!(quat_to_xyzw(&q), [0.5, 0.5, 0.5, 0.5]);
        let q = quat_from_wxyz([0.0, 1.0, 0.0, 0.0]);
        assert_eq!(quat_to_xyzw(&q), [1.0, 0.0, 0.0, 0.0]);
        assert_eq!(quat_to_wxyz(&quat_from_xyzw([1.0, 0.0, 0.0, 0.0])), [0.0, 1.0, 0.0, 0.0]);
    }

    #[test]
    fn rejects_bad_matrices() {
        let mut m = Mat4::identity();
        m[(0, 0)] = f64::NAN;
        let err = pose_from_matrix(&m, "demo_0/eef_pose[3]").unwrap_err().to_string();
        assert!(err.contains("demo_0/eef_pose[3]") && err.contains("NaN"), "{err}");
        let mut m = Mat4::identity();
        m[(0, 0)] = 2.0;
        assert!(pose_from_matrix(&m, "x").unwrap_err().to_string().contains("orthonormal"));
        let mut m = Mat4::identity();
        m[(3, 0)] = 1.0;
        assert!(pose_from_matrix(&m, "x").unwrap_err().to_string().contains("bottom row"));
        let mut m = Mat4::identity();
        m[(2, 2)] = -1.0;
        assert!(pose_from_matrix(&m, "x").unwrap_err().to_string().contains("reflection"));
    }

    #[test]
    fn distance_weights_position_and_angle() {
        let a = Pose::identity();
        let b = pose_from_parts(Vec3::new(0.3, 0.4, 0.0), rot_from_axis_angle(&Vec3::new(0.0, 0.0, 0.5)));
        let d = pose_distance(&a, &b, PoseDistanceWeights { position: 2.0, rotation: 3.0 });
        assert!((d - (2.0 * 0.5 + 3.0 * 0.5)).abs() < 1e-12);
    }

    #[test]
    fn yaw_reads_rotation_about_z() {
        let p = pose_from_parts(Vec3::zeros(), rot_from_axis_angle(&Vec3::new(0.0, 0.0, -2.0)));
        assert!((yaw_of(&p) + 2.0).abs() < 1e-12);
    }
}
