//! A run's report as one self-contained HTML page that works offline: the keyframes with
//! overlays, a 3-D view (three.js, compiled into this crate and inlined) showing the model
//! animated through the keyframes from the capture's camera and from a free orbit, score and
//! temporal plots as inline SVG, and the agent's steps on a timeline with their images.
//!
//! This crate does no I/O: the caller gathers the run into a [`Report`] (images already
//! encoded) and writes the string [`render_html`] returns.
//!
//! The page reports on itself for automated checks: once the viewer has drawn, `<body>`
//! carries `data-viewer="ready"`, `data-cam-pixels` and `data-orbit-pixels` (pixels the
//! model covers in each view), and `data-errors` (the number of script errors and
//! `console.error` calls, with their text in `data-error-text`).

mod html;
mod svg;

pub use html::render_html;
pub use svg::{line_chart, Series};

/// The three.js build inlined into every report (r170, MIT; see `assets/README.md`).
pub const THREE_JS: &str = include_str!("../assets/three.module.min.js");

/// An encoded image.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// `image/png` or `image/jpeg`.
    pub mime: String,
    pub bytes: Vec<u8>,
}

/// One keyframe.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameEntry {
    pub name: String,
    /// The captured frame (the camera view's background).
    pub frame: Image,
    /// The model rendered over the frame.
    pub overlay: Image,
    /// Visible-region IoU (hands excluded), when the frame has visible mask pixels.
    pub iou_visible: Option<f64>,
    pub iou_raw: f64,
    /// Which side of the model (and of each part) faces the camera, one line.
    pub facing: Option<String>,
}

/// A part's mesh in the object frame, metres (the run's scale applied).
#[derive(Debug, Clone, PartialEq)]
pub struct ViewerPart {
    pub name: String,
    /// Display values (sRGB-encoded, as `#rrggbb / 255`).
    pub color: [f32; 3],
    pub positions: Vec<f32>,
    pub triangles: Vec<u32>,
    /// Textures and vertex colours where the part has them; the view then draws them
    /// instead of `color`.
    pub surface: Option<ViewerSurface>,
}

/// A part's appearance for the 3-D view, per triangle corner (the triangles of
/// [`ViewerPart::triangles`], in the order of `groups`).
#[derive(Debug, Clone, PartialEq)]
pub struct ViewerSurface {
    /// Triangle indices into [`ViewerPart::triangles`] (divided by 3) in drawing order:
    /// the triangles of `groups[0]` first, then `groups[1]`'s…
    pub order: Vec<u32>,
    /// Per corner in drawing order: RGB display values that multiply the material's colour
    /// (white where the part has no vertex colours).
    pub corner_colors: Vec<f32>,
    /// Per corner in drawing order: texture coordinates (`v` down the image, glTF's
    /// convention); empty when no material has a texture.
    pub corner_uvs: Vec<f32>,
    /// Consecutive runs of `order` drawn with one material: `(triangles, material)`.
    pub groups: Vec<(u32, u32)>,
    pub materials: Vec<ViewerMaterial>,
    /// PNG images the materials name by index.
    pub textures: Vec<ViewerTexture>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ViewerMaterial {
    /// Display values.
    pub color: [f32; 3],
    pub texture: Option<u32>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ViewerTexture {
    pub png: Vec<u8>,
    /// glTF wrap codes (10497 repeat, 33648 mirrored repeat, 33071 clamp).
    pub wrap: [u32; 2],
}

/// The pose of everything at one keyframe, in the world frame. Matrices are 4×4,
/// column-major (three.js `Matrix4.fromArray`).
#[derive(Debug, Clone, PartialEq)]
pub struct ViewerFrame {
    pub name: String,
    /// `world_from_part` of every part, in [`Viewer::parts`] order.
    pub world_from_part: Vec<[f64; 16]>,
    /// `world_from_camera` (OpenCV axes: x right, y down, z forward).
    pub world_from_camera: [f64; 16],
    /// fx, fy, cx, cy in pixels.
    pub intrinsics: [f64; 4],
    pub size: [u32; 2],
    /// Joint states in display units (degrees or metres), by joint.
    pub joint_states: Vec<f64>,
}

/// The 3-D view's content.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Viewer {
    pub parts: Vec<ViewerPart>,
    pub joint_names: Vec<String>,
    pub frames: Vec<ViewerFrame>,
}

/// One step of the run's ledger.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    pub step: u64,
    pub time_s: f64,
    /// `shape`, `pose`, `diagnostic`, `note`, …
    pub kind: String,
    pub tool: String,
    pub summary: String,
    /// Scores by name, sorted.
    pub scores: Vec<(String, f64)>,
    /// Thumbnails with their captions (file names); `None` where a file could not be read.
    pub images: Vec<(String, Option<Image>)>,
}

/// The temporal report's rows, one per keyframe after the first.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Temporal {
    /// `oriented` or `camera`.
    pub pose_frame: String,
    pub frames: Vec<String>,
    pub rot_step_deg: Vec<Option<f64>>,
    /// In object sizes (translation divided by the scale).
    pub trans_step: Vec<Option<f64>>,
    pub warnings: Vec<String>,
}

/// Everything a report shows.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Report {
    pub title: String,
    /// Facts about the run, in order: capture, model, parts, joints, scale, …
    pub facts: Vec<(String, String)>,
    /// Metrics against ground truth, when the capture has it.
    pub metrics: Vec<(String, String)>,
    /// The IoU gate drawn on the score plot.
    pub gate: f64,
    pub frames: Vec<FrameEntry>,
    pub viewer: Viewer,
    pub temporal: Option<Temporal>,
    pub steps: Vec<Step>,
    /// Notes shown under the summary (ledger lines skipped, missing images, …).
    pub notes: Vec<String>,
    /// "agentstar 0.1.0" or similar.
    pub generator: String,
}
