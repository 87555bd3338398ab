//! The CPU renderer of agentstar: silhouettes (bit masks, the hot path of every search),
//! depth, part ids and shaded colour, the scores computed on them, and the images people
//! and models look at (overlays, silhouette comparisons, part-id views, turntables, the raw
//! keyframes cropped around their masks, sheets paged within the image limits of `sheet`).
//!
//! No file I/O here: images are built in memory and written by the caller.

pub mod frames;
pub mod full;
pub mod raster;
pub mod scene;
pub mod score;
pub mod sheet;
pub mod surface;
pub mod text;
pub mod views;

pub use agentstar_mask::{BitMask, DepthObservation};
pub use full::{render_full, FullRenderer, RenderBuffers, NO_PART};
pub use raster::{Affine, Instance, RowSpan, SilhouetteRenderer};
pub use scene::{visible_part_pixels, PosedModel};
pub use score::{boundary_band, IouScore, ScoreTarget, DEFAULT_BAND_PX, GATE_IOU};

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("size mismatch: {what} is {got_w}×{got_h}, expected {want_w}×{want_h}")]
    SizeMismatch {
        what: String,
        got_w: u32,
        got_h: u32,
        want_w: u32,
        want_h: u32,
    },
}
