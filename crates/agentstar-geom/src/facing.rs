//! Which side of a posed model faces the camera: for the whole model and for each part,
//! the signed axis (+X … −Z) nearest the ray from its centre to the camera and the angle
//! between them, and the angle of each model axis to that ray (0° or 180°: seen end-on,
//! 90°: seen edge-on). Parts are placed by the kinematic tree at the frame's joint states,
//! so a lid opened by its hinge reports its own axes.

use crate::model::ObjectModel;
use crate::pose::Similarity;
use crate::{Point3, Vector3};

/// The six signed axes, in the order the angles are searched.
pub const SIGNED_AXES: [&str; 6] = ["+X", "-X", "+Y", "-Y", "+Z", "-Z"];

/// A body's side toward the camera.
#[derive(Debug, Clone, PartialEq)]
pub struct Side {
    /// The signed axis nearest the ray to the camera (one of [`SIGNED_AXES`]).
    pub axis: &'static str,
    /// The angle between that axis and the ray to the camera, radians (at most ~54.7°).
    pub angle: f64,
    /// The angles of +X, +Y and +Z to the ray to the camera, radians in [0, π].
    pub axis_angles: [f64; 3],
}

/// One part's side toward the camera, in the part's own frame (its rest axes carried by
/// its joints).
#[derive(Debug, Clone, PartialEq)]
pub struct PartSide {
    pub part: String,
    pub side: Side,
    /// True when the joints move the part from its rest place at these states.
    pub moved: bool,
    /// Pixels of the part in view in the frame's render (not hidden by other parts), where
    /// the caller rendered it: a part turned toward the camera may still be hidden (a
    /// label on the far side of a can).
    pub pixels_seen: Option<u64>,
}

/// The model's side and its parts' sides toward the camera at one pose.
#[derive(Debug, Clone, PartialEq)]
pub struct Facing {
    pub model: Side,
    pub parts: Vec<PartSide>,
}

/// The side of a body toward the camera, from `toward`: the direction from the body's
/// centre to the camera, in the body's own axes.
fn side_of(toward: &Vector3) -> Side {
    let d = toward.normalize();
    let axis_angles = [
        d.x.clamp(-1.0, 1.0).acos(),
        d.y.clamp(-1.0, 1.0).acos(),
        d.z.clamp(-1.0, 1.0).acos(),
    ];
    let mut best = (0usize, f64::NEG_INFINITY);
    for k in 0..3 {
        for (s, sign) in [(0usize, 1.0f64), (1, -1.0)] {
            let c = sign * d[k];
            if c > best.1 {
                best = (2 * k + s, c);
            }
        }
    }
    Side {
        axis: SIGNED_AXES[best.0],
        angle: best.1.clamp(-1.0, 1.0).acos(),
        axis_angles,
    }
}

/// Where `model` at joint `states`, placed by `camera_from_object` (the run's scale
/// included), turns its sides: the model's from its bounding box's centre, each part's
/// from its own centre. `None` when the camera sits at the model's centre.
pub fn facing(
    model: &ObjectModel,
    states: &[f64],
    camera_from_object: &Similarity,
) -> Option<Facing> {
    let object_from_camera = camera_from_object.inverse();
    // The camera's centre in the object frame.
    let eye = object_from_camera.transform_point(&Point3::origin());
    let centre = model.posed_bounds(states).center();
    let toward = eye - centre;
    if !toward.iter().all(|v| v.is_finite()) || toward.norm() <= 1e-12 {
        return None;
    }
    let transforms = model.tree.part_transforms(states);
    let parts = model
        .parts
        .iter()
        .zip(&transforms)
        .filter_map(|(part, t)| {
            let c = t * part.bounds.center();
            let toward = t.rotation.inverse() * (eye - c);
            (toward.norm() > 1e-12).then(|| PartSide {
                part: part.name.clone(),
                side: side_of(&toward),
                moved: t.rotation.angle() > 1e-9 || t.translation.vector.norm() > 1e-9,
                pixels_seen: None,
            })
        })
        .collect();
    Some(Facing {
        model: side_of(&toward),
        parts,
    })
}

/// How an axis at `angle` (radians) to the ray is seen: `face-on` within 30° of it (or of
/// its reverse), `edge-on` within 30° of square to it, `oblique` between.
pub fn view_of(angle: f64) -> &'static str {
    let a = angle.to_degrees();
    let off_ray = a.min(180.0 - a);
    if off_ray <= 30.0 {
        "face-on"
    } else if off_ray >= 60.0 {
        "edge-on"
    } else {
        "oblique"
    }
}

impl Facing {
    /// One line: "+Z toward the camera (12° off the ray; X 88° edge-on, Y 80° edge-on,
    /// Z 12° face-on); parts: lid +Y 30° (moved), body +Z 12°". At most `max_parts` parts,
    /// moved ones first.
    pub fn line(&self, max_parts: usize) -> String {
        let m = &self.model;
        let axes: Vec<String> = ["X", "Y", "Z"]
            .iter()
            .zip(m.axis_angles)
            .map(|(n, a)| format!("+{n} {:.0}° {}", a.to_degrees(), view_of(a)))
            .collect();
        let mut s = format!(
            "{} toward the camera ({:.0}° off the ray to it; {})",
            m.axis,
            m.angle.to_degrees(),
            axes.join(", ")
        );
        if self.parts.len() > 1 {
            let mut order: Vec<&PartSide> = self.parts.iter().collect();
            order.sort_by_key(|p| !p.moved);
            let shown: Vec<String> = order
                .iter()
                .take(max_parts)
                .map(|p| {
                    format!(
                        "`{}` {} at {:.0}°{}{}",
                        p.part,
                        p.side.axis,
                        p.side.angle.to_degrees(),
                        match p.pixels_seen {
                            Some(0) => " (hidden: 0 px in view)".to_string(),
                            Some(n) => format!(" ({n} px in view)"),
                            None => String::new(),
                        },
                        if p.moved { " (moved by its joint)" } else { "" }
                    )
                })
                .collect();
            let more = self.parts.len().saturating_sub(max_parts);
            s.push_str(&format!(
                "; parts toward the camera: {}{}",
                shown.join(", "),
                if more > 0 {
                    format!(" and {more} more")
                } else {
                    String::new()
                }
            ));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{JointDef, JointKind, KinematicTree};
    use crate::model::Part;
    use crate::primitives::cuboid;
    use crate::UnitQuaternion;

    fn slab(name: &str, offset: Vector3) -> Part {
        let m = cuboid(1.0, 1.0, 0.1)
            .expect("box")
            .transformed(&crate::Matrix3::identity(), &offset);
        Part::new(name, m, [0.5, 0.5, 0.5])
    }

    #[test]
    fn the_side_toward_the_camera_and_a_hinged_lid_turned_by_its_joint() {
        // A body with a lid hinged about X at its top edge; the camera looks down −Z from
        // +Z (the object's +Z toward the camera), then from a turn of 40° about Y.
        let body = slab("body", Vector3::zeros());
        let lid = slab("lid", Vector3::new(0.0, 0.0, 0.1));
        let joint = JointDef {
            name: "hinge".into(),
            kind: JointKind::Revolute,
            parent: None,
            child: vec!["lid".into()],
            axis: Vector3::x(),
            origin: Vector3::new(0.0, 0.5, 0.1),
            limit: Some((0.0, 120.0)),
        };
        let tree = KinematicTree::new(vec![joint], &["body".to_string(), "lid".to_string()])
            .expect("tree");
        let model = ObjectModel {
            parts: vec![body, lid],
            tree,
        };
        // Object +Z toward the camera: rotate the object by π about X so +Z points to −Z_cam.
        let pose = Similarity {
            scale: 1.0,
            rotation: UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
            translation: Vector3::new(0.0, 0.0, 5.0),
        };
        let f = facing(&model, &[0.0], &pose).expect("facing");
        assert_eq!(f.model.axis, "+Z");
        assert!(f.model.angle.to_degrees() < 1.0, "{f:?}");
        assert!((f.model.axis_angles[0].to_degrees() - 90.0).abs() < 1.0);
        assert_eq!(view_of(f.model.axis_angles[0]), "edge-on");
        assert!(f.parts.iter().all(|p| !p.moved && p.side.axis == "+Z"));
        // Turned 40° about the camera's Y: +Z still toward it, 40° off.
        let turn = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 40f64.to_radians());
        let turned = Similarity {
            rotation: turn * pose.rotation,
            ..pose
        };
        let f = facing(&model, &[0.0], &turned).expect("facing");
        assert_eq!(f.model.axis, "+Z");
        assert!((f.model.angle.to_degrees() - 40.0).abs() < 2.0, "{f:?}");
        // The lid opened 70° about X: its own +Z turns away, the body's stays.
        let f = facing(&model, &[70f64.to_radians()], &pose).expect("facing");
        let lid = f.parts.iter().find(|p| p.part == "lid").expect("lid");
        let body = f.parts.iter().find(|p| p.part == "body").expect("body");
        assert!(lid.moved && !body.moved);
        // Its +Z is 70° off the ray now (±5° of perspective from its own centre), so its
        // +Y is the side nearest the camera.
        assert!(
            (lid.side.axis_angles[2].to_degrees() - 70.0).abs() < 5.0,
            "{lid:?}"
        );
        assert_eq!(lid.side.axis, "+Y", "{lid:?}");
        assert!(body.side.angle.to_degrees() < 5.0, "{body:?}");
        let line = f.line(4);
        assert!(line.starts_with("+Z toward the camera"), "{line}");
        assert!(
            line.contains("`lid`") && line.contains("moved by its joint"),
            "{line}"
        );
        assert!(!line.contains("px in view"), "no render, no pixels: {line}");
        // Where the caller rendered the frame, each part says how much of it is in view, and
        // a part turned toward the camera but hidden says so.
        let mut seen = f.clone();
        for p in &mut seen.parts {
            p.pixels_seen = Some(if p.part == "lid" { 0 } else { 1234 });
        }
        let line = seen.line(4);
        assert!(line.contains("`body` +Z at "), "{line}");
        assert!(line.contains("(1234 px in view)"), "{line}");
        assert!(line.contains("(hidden: 0 px in view)"), "{line}");
        // A camera at the centre has no side toward it.
        let inside = Similarity {
            translation: -(pose.rotation * model.posed_bounds(&[0.0]).center().coords),
            ..pose
        };
        assert!(facing(&model, &[0.0], &inside).is_none());
    }
}
