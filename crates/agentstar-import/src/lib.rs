//! Captures made from other people's data, written in our capture format with
//! `agentstar-data`'s writers: BOP scenes, HOT3D CSV sequences and ARCTIC object arrays with
//! their ground truth (`bop`, `hot3d`, `arctic`, sharing one row writer in `import_common`),
//! a video or a folder of frames (`video`, frames extracted by the `ffmpeg` command) with
//! cameras from COLMAP, nerfstudio or one static pinhole camera (`cameras`).
//!
//! The file formats of our own files live in `agentstar-data`, which knows nothing of the
//! renderer; the importers here render a silhouette of the ground truth for datasets that
//! ship no masks ([`render_parts_mask`]). Every error names the file and what is wrong.

pub mod arctic;
pub mod bop;
pub mod cameras;
pub mod hot3d;
mod import_common;
pub mod process;
pub mod video;

use agentstar_geom::pose::{Rigid, Similarity};
use agentstar_geom::{PinholeCamera, TriMesh};
use agentstar_mask::BitMask;
use agentstar_render::{Affine, Instance, SilhouetteRenderer};

/// The frames an import wrote: keyframes, and in-between frames where they were asked for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FramesWritten {
    pub keyframes: usize,
    pub between: usize,
}

/// What is wrong with an in-between stride (`--between N`, `formats.md` §2: every N-th
/// source frame between keyframes `every` source frames apart is kept too), or `None` when
/// it keeps frames: N must be at least 1 and under `every` (with `every` 1 every frame is
/// already a keyframe). Phrased with the importers' option names, which the library's
/// import configurations share.
pub fn between_stride_problem(every: usize, between: Option<usize>) -> Option<String> {
    let n = between?;
    if n == 0 {
        return Some(
            "--between 0: keep every N-th frame between keyframes, N at least 1".to_string(),
        );
    }
    if every <= 1 {
        return Some(format!(
            "--between {n} with --every {every}: every frame is a keyframe, so none lies between keyframes; keep keyframes K frames apart (--every K, K at least 2) to keep frames between them"
        ));
    }
    (n >= every).then(|| {
        format!(
            "--between {n} with --every {every}: keyframes are {every} frames apart, so an in-between stride of {n} keeps no frame between them; give N from 1 to {}",
            every - 1
        )
    })
}

/// The silhouette of ground-truth parts: each mesh with its `camera_from_part` pose. Used by
/// importers whose datasets ship no masks (the mask is then the whole object, hands not cut
/// out).
pub fn render_parts_mask(camera: &PinholeCamera, parts: &[(&TriMesh, Rigid)]) -> BitMask {
    let instances: Vec<Instance<'_>> = parts
        .iter()
        .enumerate()
        .map(|(i, (mesh, camera_from_part))| Instance {
            mesh,
            bounds: mesh.bounds(),
            camera_from_mesh: Affine::from_similarity(&Similarity::from_rigid(camera_from_part)),
            edges: None,
            open_edges: None,
            planes: None,
            part_id: i as u16,
        })
        .collect();
    let mut r = SilhouetteRenderer::new(camera.width, camera.height);
    r.render(camera, &instances).clone()
}
