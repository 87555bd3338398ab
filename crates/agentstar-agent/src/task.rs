//! The task document the agent reads (`TASK.md`), and the short instructions an MCP client
//! shows its model.

/// The gate on every keyframe's visible-region IoU (defined once, in `reports`).
pub use agentstar_render::GATE_IOU;

const TASK: &str = r#"# Your task

You are given a video of an object: keyframes, a mask of the object in each (hands cut out
and marked separately), and the camera of each keyframe. Build a model of the object **as
code** and find its pose in every keyframe, so that the model drawn into each keyframe covers
the object's mask. A capture may also keep the video frames between its keyframes:
no tool shows or scores them, but `track` follows the object through them, so each
keyframe arrives in the basin the motion carries it to; the basin of the whole sequence
(which way up, which side is which) is still yours to check.

- The model is `scene.rhai`: named parts built from primitives, joined by revolute or
  prismatic joints with limits (the API is at the end of this document). Real sizes come
  from one shared scale (metres per model unit) in `pose.json`.
- A pose is the object's rotation and position in the camera, plus the state of every joint.
  `pose.json` holds one per keyframe. You never type pose numbers: you name a search region
  and pick among the candidates the search returns.

## Conventions

- Cameras are OpenCV: +X right, +Y down, +Z forward. The model's canonical frame is +Z up,
  centred at the origin, longest side about 1; joints rest at 0.
- Camera-frame increments: `roll` (about the view axis), `yaw`, `pitch` (degrees, about the
  object's centre), `dpx`, `dpy` (fractions of the object's image size), `tz` (fraction of its
  depth). Object-frame rotations: `rx`, `ry`, `rz`, and `flip:x|y|z` (180°). Joint states:
  degrees (revolute) or model units (prismatic), absolute.
- Object-frame candidates (`oapply` sets, `oapply_all`): `rx`/`ry`/`rz` terms together are
  one rotation vector in degrees (`rz:90;rx:10` is one turn about the axis (10, 0, 90), not
  two turns); a `flip` term splits a candidate into factors applied left to right, each
  about the object's own axes as the factors before it turned them (`flip:y;rz:30` flips
  about y, then turns 30° about the flipped z). `osweep` and `oapply` turn the object
  about the centre of its bounding box at the frame's joint states, so it stays in place
  on screen; `oapply_all` turns about the canonical origin and keeps the translation.
- Scores: IoU of the rendered silhouette with the mask, counting only pixels outside the hand
  masks ("visible"). The gate is 0.98 on every keyframe, on the band IoU: the visible IoU
  without the pixels within {BAND_PX} px of the mask's outline, where a segmenter's mask is
  unsure (`score` prints both). Passing the gate means the right basin, up to a few degrees.

## How to work

Alternate two kinds of steps; **each step changes the shape or the poses, never both**.

1. **Shape step.** Look at the keyframes (`frames`: the raw input, cropped and zoomed) and
   the comparisons, then rewrite `scene.rhai` with
   `scene_write` (the whole script, as `script` or as `path`: a file you wrote in the run
   directory, e.g. `draft.rhai`). It is checked before it replaces the current one: on a
   syntax or geometry error you get the message and nothing changes. Check the result with
   `turntable` in every joint state: the 3-D shape must be coherent from every side, not only
   from the camera; for a model with joints, run `mechanism` and name with `mechanism_pick`
   the arm that moves as the object does (see the gates). Proportions you are unsure of (a depth, a handle's height) are better
   declared as parameters, `param("depth", 0.9, 0.7, 1.1)`, and fitted with `fit_shape`
   (only the parameters you name move, within their bounds, against the committed poses);
   its reply groups the residuals by viewing direction (frames face-on to each model axis,
   and the size change along X, Y, Z they want; each round tries that change): a wanted
   change the reply names as made by no fitted parameter is a fixed proportion in the
   script that is wrong, so change it there.
   `scale` estimates metres per model unit (from depth, camera parallax, a size you state,
   or, with none of these, the hands holding the object: `hand`, about ±10–20%) and
   rescales the poses.
   When a shape edit moves the canonical origin, `scene_write` and
   `fit_shape` carry every pose so that one part stays where it was in the images: the part
   most in view (by its visible pixels in the keyframes), or the one you name with `hold`;
   the result says which part was held. `check` (in `scene_write` and `scene_read`) warns about a part hidden entirely
   inside another: it never shows, so its shape and colour cannot be seen.
2. **Pose step.** Pick the worst keyframes (`score`, `temporal`), name a bounded region with
   `sweep` (camera-frame ranges and joint ranges, e.g. `yaw:-30,30;pitch:-20,20;hinge:0,90`)
   or the object-frame verbs (`osweep`, `oapply` with `flips` for near-symmetric objects,
   `oapply_all` when the model is built the wrong way round), look at the candidate sheet, and
   commit the candidate you believe with `pose_commit` (the search's report and the
   candidate's rank). A high IoU on a wrong pose (a mirror, a
   flip) is still wrong. `oapply` and
   `osweep` rows read `asked → where it ended` (the turn from the frame's pose as
   `rx;ry;rz`, the final joint states, the whole turn as an angle about an axis); commit by
   the row, never by the asked label. `hold: true` keeps `oapply`'s and `osweep`'s asked
   turns (within 3°): with `order: model`, a round body's turns ranked by its print.
   Every candidate is drawn; a note says which sheet page holds
   which ranks. `track` runs the automatic tracker over every keyframe; use it once the
   shape is right to start the poses. `track` with `from: "pose.json"` refines the current
   poses and names every frame it moved to another basin (turned over 45° from its pose
   there, with the IoU before and after and the pass that moved it); with
   `keep_basins: true` it only polishes, keeping every frame within 45° of rotation (half a
   quarter turn, so no flip or twin) and 30° of joint of the pose you settled.
   `bake` paints the model from the video; `track` with `bake: true` paints it from the
   keyframes whose outline alone settles their pose and tracks the rest with that print
   (a mug whose handle shows in some keyframes). Baked from a wrong pose, the error
   becomes the print: `bake` refuses keyframes that disagree, `track` leaves them out, and
   a symmetry every keyframe shares (a plain can, upside down) is never baked.
3. Keep notes with `notes`: what the object is, which parts move, what you ruled out. Notes
   survive when older images leave your context.

## Reading the images

The tool `render` draws these views (`views`, e.g. `"compare,side"`; default overlay and
compare; compare and side are cropped around the object, overlay shows the whole frame).
`zoom` (up to 8) and `crop` (`mask`, or a box `x0,y0,x1,y1` in frame pixels) apply to every
view of `render` (its sheets draw each crop at one size), to `frames` and to the candidate sheets of `sweep`, `apply`,
`osweep`, `oapply` and `oapply_all`: to judge a detail of a few pixels (a drinking hole, a
letter) or to tell two candidates apart by it, crop a box around it and zoom. `render` and `score` also say per keyframe
which side of the model faces the camera (`+Z toward the camera (12° off the ray; …)`,
each axis's angle to the camera ray, 0°/180° face-on, 90° edge-on) and which side of each
part (a lid at its joint state), so you need not compute it from pose.json.

- **compare** (the silhouette comparison; each image carries the same legend):
{COMPARE_LEGEND}
- **overlay**: the shaded model over the frame, part colours as in the scene.
- **frames**: the raw keyframe itself, cropped around its mask (optionally zoomed, with the
  mask's boundary in magenta, the hand's in cyan, the model's in yellow): the only view of
  the input without the model over it; use it to judge thin parts, print and texture.
  With `model: true` the posed model in its own colours, opaque, stands beside each crop at
  the same crop and zoom.
- **candidate sheet** (sweeps): one candidate a row, as the render over the frame, the
  model opaque on the frame (its print against the frame's), and its comparison, cropped
  around the object, ranked, labelled with rank, IoU and the order that produced it.
- **turntable**: eight views around the upright model (canonical +Z up) on a light
  background, one sheet per joint state (each joint's min, median and max over the
  keyframes unless you ask for others); look for parts floating, intersecting, or missing
  from the back, and for joints that move the wrong part.
- **mechanism**: each joint swept through its range about the declared axis and about
  the negated one, as arms A and B (which is declared is not shown), the other joints at
  rest, two views 40° off the axis, one column per state (labelled with its value), beside
  the keyframe showing the part most open and least under hands. One arm opens it the way
  the frames show; the other swings it the mirror way (a lid into the box).
- Every image is at most {MAX_SIDE} px on its long side and {MAX_MP} megapixels; larger
  sets come as several sheets (pages).
- **temporal plot**: rotation and translation from keyframe to keyframe after removing the
  camera's motion; a spike is either real fast motion or a wrong pose (usually a flip).

## What the tools cannot see

Every score here compares silhouettes. Four kinds of error leave the silhouette unchanged,
so a high IoU does not rule them out:

- **Symmetric twins.** An object that looks alike from two sides (a box, a bottle, a mug
  seen end-on) has a flipped pose with the same outline (a square prism, quarter turns
  too). Check: `oapply` and compare the candidates' tiles and `step°`, not their scores;
  look at `frames` for print, a handle, a logo that tells the sides apart.
- **Joint aliasing.** A revolute joint with a full-turn limit (`[0, 360]`) reaches both θ
  and 360−θ, and a part symmetric about its axis looks the same at both; a joint that
  sits at its limit in many keyframes often has its axis reversed or its limit too tight.
  Check: limit joints to the range they really move (the scene check warns about full
  turns); look at `turntable` at the joint's min, median and max (it warns when many
  keyframes sit at a limit; `acknowledge_limits: true` shortens one you checked) and at `frames` where the part is visible.
- **A mirrored joint axis.** A hinge declared about −x instead of +x moves its part the
  mirror way, yet at the keyframes' states the tracker can still fit the outline (with the
  states negated, or the part swung through the body). Check: `mechanism`, and name the
  arm whose motion matches the frames with `mechanism_pick`; if it is the negated arm,
  negate the axis in the scene (or keep it and swap the limit to [−upper, −lower]).
- **A mirror-image model.** A model built the mirror image of the object (a handle, a ring
  or a part on the wrong side; two blades layered the wrong way round) fits most
  silhouettes, and no pose, flip or swap can fix it: a reflection is not a turn. Check:
  `frames` with the model's outline, or `render` views `side`, where the parts' order or
  sides show; mirror the script (negate the coordinate across the plane) if it is.
- **Scale.** A larger object farther away casts the same silhouette: the IoU cannot tell
  the scale from the distance. Check: use depth when the capture has it (the depth error
  in `score`), a size you know ("the laptop is 30 cm wide"), or a moving camera's
  parallax, each a method of the `scale` tool; with none of these, the hands holding the
  object (`hand`: an adult palm is about 7.9 cm across) give a rough scale with its
  uncertainty stated; keep proportions from the frames, not from the IoU.

## Gates before you finish

Call `finish` only when all of these hold; it checks them and tells you what is missing:

1. Every keyframe's band IoU ≥ 0.98, or a reason for each keyframe that cannot reach it,
   given to `finish` in one of its categories, each checked: `occlusion` (more of the object
   hidden than the run's threshold, 30% by default), `mask_error` (name an image that shows
   it), `truncated` (cut by the frame border), `out_of_reach` (what the model cannot do, in a
   note). At most a quarter of the keyframes may be under the gate, reasons or not. For
   example: `{"unreachable": {"000050": {"category": "out_of_reach", "note": "the lid bends
   here; the model's lid is rigid"}}}`.
2. `turntable` was looked at after the last shape change, and the shape is coherent in every
   joint state.
3. `temporal` was looked at after the last pose change (a rescale is one), and every large
   step is confirmed or fixed. A step over 90° that stays is named in `finish`'s
   `steps_checked` with what you found, after `oapply` (or `osweep`, `render`, `frames`) on
   one of its frames since their last pose change: `{"steps_checked": {"000040->000045":
   "oapply: no twin within 0.01"}}`.
4. Every revolute joint of the current scene has a `mechanism_pick` made for this scene
   version that names the arm about the declared axis. Run `mechanism`, compare arms A and
   B with the frames, and pick with evidence naming at least three interior states by
   value: `{"picks": {"lid_hinge": {"arm": "A", "evidence": "at 37 deg the lid clears the
   rim; at 55 deg it stands over the back; at 92 deg it leans back as in 000040"}}}`. A
   scene change makes a pick stale (sweep and pick again); picking the negated arm blocks
   `finish` until the axis is negated in the scene. A run can switch this gate off in
   `run.json` (`"finish": {"mechanism_check": false}`).

## Budgets

A run has limits on steps, wall time and tokens; the harness tells you what is left. Spend
early steps on the shape (it limits every pose), then poses, then the gates. Never repeat a
failed search: change the region or the shape.

"#;

/// The compare legend as TASK.md writes it: one line per colour of
/// [`agentstar_render::views::COMPARE_LEGEND`] (the constants the images are drawn with),
/// with its name, its `#rrggbb` and what it means.
pub fn compare_legend_markdown() -> String {
    use agentstar_render::views::{hex, COMPARE_LEGEND};
    COMPARE_LEGEND
        .iter()
        .map(|e| {
            format!(
                "  - {} (`{}`{}): {}",
                e.name,
                hex(e.colour),
                if e.hand_only {
                    ", only where the capture has hand masks"
                } else {
                    ""
                },
                e.meaning
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The task document: how to work, the gates, and the scene API with a worked example.
pub fn task_document() -> String {
    use agentstar_render::sheet::{MAX_LONG_SIDE_PX, MAX_PIXELS};
    let mut s = TASK
        .replace("{COMPARE_LEGEND}", &compare_legend_markdown())
        .replace("{MAX_SIDE}", &MAX_LONG_SIDE_PX.to_string())
        .replace("{MAX_MP}", &format!("{:.2}", MAX_PIXELS as f64 / 1e6))
        .replace("{BAND_PX}", &agentstar_render::DEFAULT_BAND_PX.to_string());
    s.push_str("# The scene API\n\n");
    let scene = include_str!("../../../docs/scene.md");
    // The scene document's own title is replaced by the heading above.
    let body = scene
        .split_once('\n')
        .map(|(_, rest)| rest)
        .unwrap_or(scene);
    s.push_str(body.trim_start());
    s
}

/// [`MCP_INSTRUCTIONS`] as a server without a critic model gives them: `critic` is not
/// among the tools it lists, so the instructions do not name it.
pub fn mcp_instructions(with_critic: bool) -> String {
    if with_critic {
        MCP_INSTRUCTIONS.to_string()
    } else {
        MCP_INSTRUCTIONS.replace(", pose_diff, critic.", ", pose_diff.")
    }
}

/// What an MCP client shows its model when it connects (with a critic model: see
/// [`mcp_instructions`]).
pub const MCP_INSTRUCTIONS: &str = "agentstar fits an object model written as code (scene.rhai) and its pose in every keyframe of a video to the object's masks. Read TASK.md in the run directory first (the tool `task` returns it): it explains the loop (each step changes the shape or the poses, never both), how to read the images, and the gates `finish` checks. Shape tools: scene_read, scene_write, scene_restore, fit_shape, bake, scale, turntable, mechanism, mechanism_pick. Pose tools: track, sweep, apply, osweep, oapply, oapply_all, pose_commit, pose_history, pose_restore. Diagnostics: frames (the raw keyframes, cropped around the mask), render, score, temporal, pose_diff, critic. Images come back inline and as files under the run's images/ directory.";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_compare_legend_is_the_one_the_images_are_drawn_with() {
        use agentstar_render::views::{colour_name, comparison_legend, hex, COMPARE_LEGEND};
        let t = task_document();
        for hole in ["{COMPARE_LEGEND}", "{MAX_SIDE}", "{MAX_MP}", "{BAND_PX}"] {
            assert!(!t.contains(hole), "{hole}");
        }
        // Every colour of the images' legend is in TASK.md, under its own name, which
        // names the colour it is (a constant changed without its name fails here).
        for e in COMPARE_LEGEND {
            let line = t
                .lines()
                .find(|l| l.contains(&format!("`{}`", hex(e.colour))))
                .unwrap_or_else(|| panic!("TASK.md has no line for {}", hex(e.colour)));
            assert!(line.contains(e.name), "{line}");
            assert_eq!(colour_name(e.colour), e.name, "{e:?}");
        }
        // ... and the image legend draws exactly the swatch colours TASK.md lists.
        for (c, _) in comparison_legend(true) {
            assert!(t.contains(&hex(c)), "{}", hex(c));
        }
        // The old, wrong legend is gone.
        assert!(!t.contains("red = mask") && !t.contains("white = background"));
        assert!(t.contains("What the tools cannot see"));
        for topic in ["Symmetric twins", "Joint aliasing", "Scale"] {
            assert!(t.contains(topic), "{topic}");
        }
        assert!(t.contains("1568 px"));
    }

    #[test]
    fn the_task_document_holds_the_gates_and_the_whole_scene_api() {
        let t = task_document();
        assert!(t.contains("0.98") && t.contains("finish"));
        // Without a critic model the instructions do not name the critic.
        assert!(mcp_instructions(true).contains("pose_diff, critic."));
        let without = mcp_instructions(false);
        assert!(
            !without.contains("critic") && without.contains("pose_diff."),
            "{without}"
        );
        // The mechanism gate: how to pass it and how a run turns it off.
        assert!(t.contains("mechanism_pick") && t.contains("mechanism_check"));
        assert!(without.contains("turntable, mechanism, mechanism_pick."));
        assert!(t.contains("A worked articulated example"));
        assert!(t.contains("joint("));
        // Short enough to read whole: under ~5,000 words.
        assert!(
            t.split_whitespace().count() < 5000,
            "{}",
            t.split_whitespace().count()
        );
    }
}
