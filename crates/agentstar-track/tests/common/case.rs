//! The synthetic articulated object and motion shared by the tests and the benchmarks.

use agentstar_geom::csg::{difference, union};
use agentstar_geom::pose::ObjectPose;
use agentstar_geom::primitives::{bevelled_box, cuboid, torus};
use agentstar_geom::{ObjectModel, Part, UnitQuaternion, Vector3};

use agentstar_track::update::GenPose;
use hinged::with_lid_hinge;

// By path, so that the benchmark that includes this file finds it too.
#[path = "hinged.rs"]
pub mod hinged;

/// A carrying case with a hinged lid and a handle on the front (no rotational symmetry).
pub fn case_model() -> ObjectModel {
    let shell = difference(
        &bevelled_box(1.0, 0.62, 0.26, 0.02, 2).expect("box"),
        &cuboid(0.92, 0.54, 0.3)
            .expect("box")
            .translated(Vector3::new(0.0, 0.0, 0.06)),
    )
    .expect("hollow");
    let rot = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2)
        .into_inner();
    let handle = torus(0.08, 0.022, 24, 8)
        .expect("torus")
        .transformed(&rot, &Vector3::new(0.25, -0.33, 0.02));
    let base = union(&shell.translated(Vector3::new(0.0, 0.0, -0.06)), &handle).expect("base");
    let lid = bevelled_box(1.0, 0.62, 0.08, 0.02, 2)
        .expect("lid")
        .translated(Vector3::new(0.0, 0.0, 0.11));
    let parts = vec![
        Part::new("base", base, [0.2, 0.4, 0.7]),
        Part::new("lid", lid, [0.9, 0.6, 0.2]),
    ];
    with_lid_hinge(parts, Vector3::new(0.0, 0.31, 0.07), -Vector3::x(), 120.0)
}

pub fn truth(t: f64) -> GenPose {
    // Steps of up to 90° between keyframes about a turning axis, lid opening and closing.
    let a = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 110f64.to_radians());
    let spin = UnitQuaternion::from_axis_angle(
        &nalgebra::Unit::new_normalize(Vector3::new(0.2, 1.0, 0.3)),
        (t * 75.0 + 15.0 * (t * 0.7).sin()).to_radians(),
    );
    let pose = ObjectPose::new(
        spin * a,
        Vector3::new(
            0.05 * (t * 0.5).sin(),
            0.03 * (t * 0.3).cos(),
            1.2 + 0.1 * (t * 0.4).sin(),
        ),
    );
    GenPose {
        pose,
        states: vec![(60.0 + 45.0 * (t * 0.9).sin()).to_radians()],
    }
}
