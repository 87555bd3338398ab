//! What a keyframe shows of the object, in the two forms every other crate shares: bit-packed
//! binary masks ([`BitMask`]: the object's mask, the hand mask, a rendered silhouette) and
//! planar depth with per-pixel confidence ([`DepthObservation`]).
//!
//! This crate depends on nothing: the renderer draws into its masks and scores against them,
//! and the file formats read images into them, without either knowing the other.

pub mod bitmask;
pub mod depth;

pub use bitmask::BitMask;
pub use depth::DepthObservation;
