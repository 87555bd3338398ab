//! Geometry for agentstar: poses, cameras, triangle meshes, primitive meshing, booleans
//! and the kinematic tree with its forward kinematics.
//!
//! This crate does no I/O and knows nothing about files, images or networks. Angles are
//! radians everywhere in this crate; degrees appear only at the edges (scene scripts,
//! `pose.json`), where the conversion is named explicitly (`angle_deg`).

pub mod appearance;
pub mod atlas;
pub mod camera;
pub mod csg;
pub mod facing;
pub mod hull;
pub mod inside;
pub mod kinematics;
pub mod mesh;
pub mod model;
pub mod nearest;
pub mod pose;
pub mod primitives;
pub mod simplify;
pub mod truth;

pub use appearance::{AppearedMesh, Material, SurfaceAppearance, Texture, WrapMode};
pub use atlas::{tessellation_fingerprint, with_atlas, AtlasLayout, AtlasTransfer, Patch};
pub use camera::PinholeCamera;
pub use kinematics::{JointDef, JointKind, KinematicTree};
pub use mesh::{Aabb, TriMesh};
pub use model::{
    held_part, origin_shift, origin_shift_holding, CanonicalReport, HeldPart, ObjectModel,
    OriginShift, Part,
};
pub use pose::{GenPose, ObjectPose, Similarity};

/// Errors of the geometry layer. Messages name the offending value and say what is valid.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum GeomError {
    #[error("invalid argument to `{primitive}`: {reason}")]
    InvalidArgument { primitive: String, reason: String },
    #[error("invalid joint `{joint}`: {reason}")]
    InvalidJoint { joint: String, reason: String },
    #[error("invalid kinematic tree: {0}")]
    InvalidTree(String),
    #[error("invalid pose: {0}")]
    InvalidPose(String),
    #[error("mesh too large: {triangles} triangles exceeds the limit of {limit}")]
    MeshTooLarge { triangles: usize, limit: usize },
    /// A bounded computation (a boolean) reached its time or size limit.
    #[error("{0}")]
    LimitExceeded(String),
}

pub type Result<T, E = GeomError> = std::result::Result<T, E>;

pub use nalgebra;
pub type Point3 = nalgebra::Point3<f64>;
pub type Vector3 = nalgebra::Vector3<f64>;
pub type Matrix3 = nalgebra::Matrix3<f64>;
pub type Matrix4 = nalgebra::Matrix4<f64>;
pub type UnitQuaternion = nalgebra::UnitQuaternion<f64>;
