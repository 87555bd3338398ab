//! The functions a scene script can call, their registration with a sandboxed Rhai engine,
//! and the evaluation that turns a script into an object model.

use crate::api_table::{api_names, API};
use crate::colors::{parse_color, PALETTE};
use crate::diagnostics::{did_you_mean, SceneError, SceneErrorKind};
use crate::preload::Preloaded;
use crate::{Limits, MeshSource, ParamDecl, SceneBuild};
use agentstar_geom::kinematics::{JointDef, JointKind};
use agentstar_geom::{
    csg, primitives as prim, KinematicTree, Matrix3, ObjectModel, Part, Point3, SurfaceAppearance,
    TriMesh, UnitQuaternion, Vector3,
};
use rhai::{Array, Dynamic, Engine, EvalAltResult, Map, Position, AST};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

const JOINT_KEYS: [&str; 7] = ["axis", "child", "limit", "name", "origin", "parent", "type"];

/// A solid value in a script: an immutable mesh, an optional colour, and the appearance
/// of an imported mesh file (kept through transforms; a boolean or `color` replaces it
/// with one colour).
#[derive(Debug, Clone)]
pub struct Solid {
    mesh: Arc<TriMesh>,
    color: Option<[f32; 3]>,
    surface: Option<Arc<SurfaceAppearance>>,
}

struct State {
    parts: Vec<(String, Solid)>,
    /// What reading mesh files and dropping their appearance in booleans gave to say.
    notes: Vec<String>,
    joints: Vec<(JointDef, Position)>,
    triangles: usize,
    printed: Vec<String>,
    /// Shape parameters in the order the script declared them.
    params: Vec<ParamDecl>,
    /// Values to use instead of the declared ones (`fit_shape`'s trials).
    overrides: BTreeMap<String, f64>,
    limits: Limits,
    /// When the script's wall-time limit runs out; booleans stop there too.
    deadline: Instant,
}

impl State {
    fn boolean_budget(&self) -> csg::Budget {
        csg::Budget {
            deadline: Some(self.deadline),
            // Splitting may multiply polygons; a few times the triangle limit is the most a
            // result could still be admitted with.
            max_polygons: self.limits.max_triangles.saturating_mul(4),
        }
    }
}

type Shared = Arc<Mutex<State>>;
type RResult<T> = Result<T, Box<EvalAltResult>>;

fn fail<T>(msg: impl Into<String>) -> RResult<T> {
    Err(Box::new(EvalAltResult::ErrorRuntime(
        Dynamic::from(msg.into()),
        Position::NONE,
    )))
}

fn lock(state: &Shared) -> std::sync::MutexGuard<'_, State> {
    // A poisoned lock only means an earlier call panicked; the data is still usable.
    state.lock().unwrap_or_else(|e| e.into_inner())
}

fn num(d: &Dynamic, func: &str, param: &str) -> RResult<f64> {
    if let Ok(f) = d.as_float() {
        Ok(f)
    } else if let Ok(i) = d.as_int() {
        Ok(i as f64)
    } else {
        fail(format!(
            "`{func}`: argument `{param}` must be a number, got {}",
            d.type_name()
        ))
    }
}

fn int(d: &Dynamic, func: &str, param: &str) -> RResult<i64> {
    if let Ok(i) = d.as_int() {
        return Ok(i);
    }
    let f = num(d, func, param)?;
    if f.fract() != 0.0 {
        return fail(format!(
            "`{func}`: argument `{param}` must be a whole number, got {f}"
        ));
    }
    Ok(f as i64)
}

fn numbers(d: &Dynamic, func: &str, param: &str, len: usize) -> RResult<Vec<f64>> {
    let Some(arr) = d.clone().try_cast::<Array>() else {
        return fail(format!(
            "`{func}`: `{param}` must be an array of {len} numbers like [0.0, 0.0, 1.0], got {}",
            d.type_name()
        ));
    };
    if arr.len() != len {
        return fail(format!(
            "`{func}`: `{param}` must have {len} numbers, got {}",
            arr.len()
        ));
    }
    arr.iter().map(|x| num(x, func, param)).collect()
}

fn vec3(d: &Dynamic, func: &str, param: &str) -> RResult<Vector3> {
    let v = numbers(d, func, param, 3)?;
    Ok(Vector3::new(v[0], v[1], v[2]))
}

fn point_list(d: &Dynamic, func: &str, param: &str, dim: usize) -> RResult<Vec<Vec<f64>>> {
    let Some(arr) = d.clone().try_cast::<Array>() else {
        return fail(format!(
            "`{func}`: `{param}` must be an array of points, got {}",
            d.type_name()
        ));
    };
    arr.iter()
        .enumerate()
        .map(|(i, p)| numbers(p, func, &format!("{param}[{i}]"), dim))
        .collect()
}

fn pairs(d: &Dynamic, func: &str, param: &str) -> RResult<Vec<(f64, f64)>> {
    Ok(point_list(d, func, param, 2)?
        .into_iter()
        .map(|p| (p[0], p[1]))
        .collect())
}

fn to_array(v: &Vector3) -> Array {
    v.iter().map(|&c| Dynamic::from_float(c)).collect()
}

impl Solid {
    fn mapped(&self, linear: &Matrix3, offset: &Vector3) -> Solid {
        // A mirroring map swaps each triangle's last two corners; their attributes follow.
        let surface = match &self.surface {
            Some(s) if linear.determinant() < 0.0 => Some(Arc::new(s.with_corners_swapped())),
            s => s.clone(),
        };
        Solid {
            mesh: Arc::new((*self.mesh).clone().transformed(linear, offset)),
            color: self.color,
            surface,
        }
    }

    /// The one colour this solid gives a boolean's result: its own, or its surface's mean.
    fn plain_color(&self) -> Option<[f32; 3]> {
        self.color
            .or_else(|| self.surface.as_ref().map(|s| s.mean_color(&self.mesh)))
    }
}

/// A boolean's result colour, noting once per call when an operand's texture or vertex
/// colours are replaced by their mean.
fn boolean_color(state: &Shared, op: &str, solids: &[&Solid]) -> Option<[f32; 3]> {
    if solids.iter().any(|s| s.surface.is_some()) {
        let note = format!("`{op}` replaces the texture and vertex colours of an imported mesh by their mean colour (a boolean keeps one colour); make the textured mesh a part of its own to keep them");
        let mut s = lock(state);
        if !s.notes.contains(&note) {
            s.notes.push(note);
        }
    }
    solids.iter().find_map(|s| s.plain_color())
}

/// Records a new mesh against the triangle budget.
fn admit(state: &Shared, mesh: TriMesh, color: Option<[f32; 3]>) -> RResult<Solid> {
    let mut s = lock(state);
    s.triangles += mesh.triangles.len();
    if s.triangles > s.limits.max_triangles {
        return fail(format!(
            "the script created {} triangles in total, over the limit of {}; use fewer segments",
            s.triangles, s.limits.max_triangles
        ));
    }
    if !mesh.is_finite() {
        return fail("the operation produced non-finite coordinates");
    }
    Ok(Solid {
        mesh: Arc::new(mesh),
        color,
        surface: None,
    })
}

fn geom<T>(r: agentstar_geom::Result<T>) -> RResult<T> {
    r.or_else(|e| match e {
        // A limit stops the script as the wall-time limit of the engine does.
        agentstar_geom::GeomError::LimitExceeded(m) => Err(Box::new(
            EvalAltResult::ErrorTerminated(Dynamic::from(m), Position::NONE),
        )),
        e => fail(e.to_string()),
    })
}

fn axis_rotation(axis: Vector3, angle_deg: f64, func: &str) -> RResult<Matrix3> {
    if !angle_deg.is_finite() {
        return fail(format!("`{func}`: angle {angle_deg} is not finite"));
    }
    let Some(unit) = agentstar_geom::nalgebra::Unit::try_new(axis, 1e-12) else {
        return fail(format!(
            "`{func}`: axis {:?} has zero length",
            axis.as_slice()
        ));
    };
    Ok(
        UnitQuaternion::from_axis_angle(&unit, angle_deg.to_radians())
            .to_rotation_matrix()
            .into_inner(),
    )
}

fn parse_joint(map: &Map) -> RResult<JointDef> {
    for key in map.keys() {
        if !JOINT_KEYS.contains(&key.as_str()) {
            return fail(format!(
                "`joint`: unknown key `{key}`{}; valid keys are {}",
                did_you_mean(key, &JOINT_KEYS),
                JOINT_KEYS.join(", ")
            ));
        }
    }
    let get = |k: &str| map.get(k);
    let name = match get("name").and_then(|d| d.clone().into_string().ok()) {
        Some(n) if !n.is_empty() => n,
        _ => return fail("`joint`: `name` must be a non-empty string"),
    };
    let ctx = format!("joint `{name}`");
    let type_str = get("type")
        .and_then(|d| d.clone().into_string().ok())
        .unwrap_or_default();
    let Some(kind) = JointKind::parse(&type_str) else {
        return fail(format!(
            "{ctx}: `type` must be one of {}, got `{type_str}`{}",
            JointKind::NAMES.join(", "),
            did_you_mean(&type_str, &JointKind::NAMES)
        ));
    };
    let child = match get("child") {
        Some(d) if d.is_string() => vec![d.clone().into_string().unwrap_or_default()],
        Some(d) if d.is_array() => {
            let arr = d.clone().cast::<Array>();
            let mut v = Vec::new();
            for c in arr {
                match c.into_string() {
                    Ok(s) => v.push(s),
                    Err(t) => {
                        return fail(format!(
                            "{ctx}: `child` entries must be part names (strings), got {t}"
                        ))
                    }
                }
            }
            v
        }
        _ => {
            return fail(format!(
                "{ctx}: `child` must be a part name or a list of part names"
            ))
        }
    };
    let origin = match get("origin") {
        Some(d) => vec3(d, &ctx, "origin")?,
        None => Vector3::zeros(),
    };
    let axis = match get("axis") {
        Some(d) => vec3(d, &ctx, "axis")?,
        None if kind == JointKind::Fixed => Vector3::z(),
        None => return fail(format!("{ctx}: `axis` is required, e.g. axis: [1, 0, 0]")),
    };
    let limit = match get("limit") {
        Some(d) if !d.is_unit() => {
            let v = numbers(d, &ctx, "limit", 2)?;
            Some((v[0], v[1]))
        }
        _ => None,
    };
    if kind == JointKind::Continuous && limit.is_some() {
        return fail(format!(
            "{ctx}: a continuous joint has no limit; use type \"revolute\" for a limited rotation"
        ));
    }
    let parent = match get("parent") {
        Some(d) if d.is_unit() => None,
        Some(d) => match d.clone().into_string() {
            Ok(s) => Some(s),
            Err(t) => return fail(format!("{ctx}: `parent` must be a joint name, got {t}")),
        },
        None => None,
    };
    Ok(JointDef {
        name,
        kind,
        parent,
        child,
        origin,
        axis,
        limit,
    })
}

fn register(engine: &mut Engine, state: &Shared, meshes: Arc<dyn MeshSource>) {
    engine.register_type_with_name::<Solid>("Solid");

    macro_rules! prim {
        ($name:literal, |$($arg:ident),*| $body:expr) => {{
            let st = state.clone();
            engine.register_fn($name, move |$($arg: Dynamic),*| -> RResult<Solid> {
                let mesh = $body;
                admit(&st, mesh, None)
            });
        }};
    }

    prim!("box", |x, y, z| geom(prim::cuboid(
        num(&x, "box", "size_x")?,
        num(&y, "box", "size_y")?,
        num(&z, "box", "size_z")?
    ))?);
    prim!("box", |x, y, z, b| geom(prim::bevelled_box(
        num(&x, "box", "size_x")?,
        num(&y, "box", "size_y")?,
        num(&z, "box", "size_z")?,
        num(&b, "box", "bevel")?,
        4
    ))?);
    prim!("box", |x, y, z, b, n| geom(prim::bevelled_box(
        num(&x, "box", "size_x")?,
        num(&y, "box", "size_y")?,
        num(&z, "box", "size_z")?,
        num(&b, "box", "bevel")?,
        int(&n, "box", "segments")?
    ))?);
    prim!("cylinder", |r, h| geom(prim::cylinder(
        num(&r, "cylinder", "radius")?,
        num(&h, "cylinder", "height")?,
        48
    ))?);
    prim!("cylinder", |r, h, n| geom(prim::cylinder(
        num(&r, "cylinder", "radius")?,
        num(&h, "cylinder", "height")?,
        int(&n, "cylinder", "segments")?
    ))?);
    prim!("sector", |r, h, a| geom(prim::sector(
        num(&r, "sector", "radius")?,
        num(&h, "sector", "height")?,
        num(&a, "sector", "angle_deg")?,
        48
    ))?);
    prim!("sector", |r, h, a, n| geom(prim::sector(
        num(&r, "sector", "radius")?,
        num(&h, "sector", "height")?,
        num(&a, "sector", "angle_deg")?,
        int(&n, "sector", "segments")?
    ))?);
    prim!("cone", |a, b, h| geom(prim::cone(
        num(&a, "cone", "radius_bottom")?,
        num(&b, "cone", "radius_top")?,
        num(&h, "cone", "height")?,
        48
    ))?);
    prim!("cone", |a, b, h, n| geom(prim::cone(
        num(&a, "cone", "radius_bottom")?,
        num(&b, "cone", "radius_top")?,
        num(&h, "cone", "height")?,
        int(&n, "cone", "segments")?
    ))?);
    prim!("sphere", |r| geom(prim::uv_sphere(
        num(&r, "sphere", "radius")?,
        32,
        16
    ))?);
    prim!("sphere", |r, n, m| geom(prim::uv_sphere(
        num(&r, "sphere", "radius")?,
        int(&n, "sphere", "segments")?,
        int(&m, "sphere", "rings")?
    ))?);
    prim!("ico_sphere", |r| geom(prim::ico_sphere(
        num(&r, "ico_sphere", "radius")?,
        2
    ))?);
    prim!("ico_sphere", |r, n| geom(prim::ico_sphere(
        num(&r, "ico_sphere", "radius")?,
        int(&n, "ico_sphere", "subdivisions")?
    ))?);
    prim!("torus", |a, b| geom(prim::torus(
        num(&a, "torus", "major_radius")?,
        num(&b, "torus", "minor_radius")?,
        48,
        16
    ))?);
    prim!("torus", |a, b, n, m| geom(prim::torus(
        num(&a, "torus", "major_radius")?,
        num(&b, "torus", "minor_radius")?,
        int(&n, "torus", "segments")?,
        int(&m, "torus", "minor_segments")?
    ))?);
    prim!("capsule", |r, l| geom(prim::capsule(
        num(&r, "capsule", "radius")?,
        num(&l, "capsule", "length")?,
        32
    ))?);
    prim!("capsule", |r, l, n| geom(prim::capsule(
        num(&r, "capsule", "radius")?,
        num(&l, "capsule", "length")?,
        int(&n, "capsule", "segments")?
    ))?);
    prim!("plane", |x, y| geom(prim::plane(
        num(&x, "plane", "size_x")?,
        num(&y, "plane", "size_y")?
    ))?);
    prim!("disc", |r| geom(prim::disc(
        num(&r, "disc", "radius")?,
        48
    ))?);
    prim!("disc", |r, n| geom(prim::disc(
        num(&r, "disc", "radius")?,
        int(&n, "disc", "segments")?
    ))?);
    prim!("wedge", |x, y, z| geom(prim::wedge(
        num(&x, "wedge", "size_x")?,
        num(&y, "wedge", "size_y")?,
        num(&z, "wedge", "size_z")?
    ))?);
    prim!("hull", |p| {
        let pts: Vec<Point3> = point_list(&p, "hull", "points", 3)?
            .into_iter()
            .map(|v| Point3::new(v[0], v[1], v[2]))
            .collect();
        geom(agentstar_geom::hull::convex_hull(&pts))?
    });
    prim!("extrude", |o, h| geom(prim::extrude(
        &pairs(&o, "extrude", "outline")?,
        &[],
        num(&h, "extrude", "height")?
    ))?);
    prim!("extrude", |o, holes, h| {
        let Some(hs) = holes.clone().try_cast::<Array>() else {
            return fail("`extrude`: `holes` must be a list of polygons");
        };
        let holes: Vec<Vec<(f64, f64)>> = hs
            .iter()
            .enumerate()
            .map(|(i, p)| pairs(p, "extrude", &format!("holes[{i}]")))
            .collect::<RResult<_>>()?;
        geom(prim::extrude(
            &pairs(&o, "extrude", "outline")?,
            &holes,
            num(&h, "extrude", "height")?,
        ))?
    });
    prim!("lathe", |p| geom(prim::lathe(
        &pairs(&p, "lathe", "profile")?,
        48
    ))?);
    prim!("lathe", |p, n| geom(prim::lathe(
        &pairs(&p, "lathe", "profile")?,
        int(&n, "lathe", "segments")?
    ))?);
    {
        let st = state.clone();
        engine.register_fn("mesh", move |path: &str| -> RResult<Solid> {
            let m = meshes
                .load(path)
                .or_else(|e| fail(format!("`mesh`: {e}")))?;
            {
                let mut s = lock(&st);
                for w in &m.warnings {
                    let note = format!("`mesh(\"{path}\")`: {w}");
                    if !s.notes.contains(&note) {
                        s.notes.push(note);
                    }
                }
            }
            let mut solid = admit(&st, m.mesh, None)?;
            solid.surface = m.surface;
            Ok(solid)
        });
    }

    // Booleans.
    type Op = fn(&TriMesh, &TriMesh, csg::Budget) -> agentstar_geom::Result<TriMesh>;
    let ops: [(&str, Op); 5] = [
        ("union", csg::union_within),
        ("+", csg::union_within),
        ("difference", csg::difference_within),
        ("-", csg::difference_within),
        ("intersection", csg::intersection_within),
    ];
    for (name, op) in ops {
        let st = state.clone();
        engine.register_fn(name, move |a: Solid, b: Solid| -> RResult<Solid> {
            let budget = lock(&st).boolean_budget();
            let m = geom(op(&a.mesh, &b.mesh, budget))?;
            let color = boolean_color(&st, name, &[&a, &b]);
            admit(&st, m, color)
        });
    }
    {
        let st = state.clone();
        engine.register_fn("union_all", move |list: Array| -> RResult<Solid> {
            let mut solids = Vec::new();
            for (i, d) in list.into_iter().enumerate() {
                match d.try_cast::<Solid>() {
                    Some(s) => solids.push(s),
                    None => return fail(format!("`union_all`: item {i} is not a solid")),
                }
            }
            let Some(first) = solids.first().cloned() else {
                return fail("`union_all`: the list is empty");
            };
            let mut acc = (*first.mesh).clone();
            let budget = lock(&st).boolean_budget();
            for s in &solids[1..] {
                acc = geom(csg::union_within(&acc, &s.mesh, budget))?;
            }
            let color = boolean_color(&st, "union_all", &solids.iter().collect::<Vec<_>>());
            admit(&st, acc, color)
        });
    }

    // Transforms.
    engine.register_fn(
        "translate",
        |s: &mut Solid, x: Dynamic, y: Dynamic, z: Dynamic| -> RResult<Solid> {
            let v = Vector3::new(
                num(&x, "translate", "x")?,
                num(&y, "translate", "y")?,
                num(&z, "translate", "z")?,
            );
            if !v.iter().all(|c| c.is_finite()) {
                return fail("`translate`: offsets must be finite");
            }
            Ok(s.mapped(&Matrix3::identity(), &v))
        },
    );
    engine.register_fn("translate", |s: &mut Solid, v: Dynamic| -> RResult<Solid> {
        Ok(s.mapped(&Matrix3::identity(), &vec3(&v, "translate", "offset")?))
    });
    engine.register_fn(
        "rotate",
        |s: &mut Solid, axis: Dynamic, angle: Dynamic| -> RResult<Solid> {
            let r = axis_rotation(
                vec3(&axis, "rotate", "axis")?,
                num(&angle, "rotate", "angle_deg")?,
                "rotate",
            )?;
            Ok(s.mapped(&r, &Vector3::zeros()))
        },
    );
    for (name, axis) in [
        ("rotate_x", Vector3::x()),
        ("rotate_y", Vector3::y()),
        ("rotate_z", Vector3::z()),
    ] {
        engine.register_fn(
            name,
            move |s: &mut Solid, angle: Dynamic| -> RResult<Solid> {
                let r = axis_rotation(axis, num(&angle, name, "angle_deg")?, name)?;
                Ok(s.mapped(&r, &Vector3::zeros()))
            },
        );
    }
    engine.register_fn(
        "rotate_euler",
        |s: &mut Solid, x: Dynamic, y: Dynamic, z: Dynamic| -> RResult<Solid> {
            let rx = axis_rotation(
                Vector3::x(),
                num(&x, "rotate_euler", "x_deg")?,
                "rotate_euler",
            )?;
            let ry = axis_rotation(
                Vector3::y(),
                num(&y, "rotate_euler", "y_deg")?,
                "rotate_euler",
            )?;
            let rz = axis_rotation(
                Vector3::z(),
                num(&z, "rotate_euler", "z_deg")?,
                "rotate_euler",
            )?;
            Ok(s.mapped(&(rz * ry * rx), &Vector3::zeros()))
        },
    );
    engine.register_fn("scale", |s: &mut Solid, f: Dynamic| -> RResult<Solid> {
        let f = num(&f, "scale", "factor")?;
        if !(f.is_finite() && f > 0.0) {
            return fail(format!(
                "`scale`: factor must be positive and finite, got {f} (use mirror to flip)"
            ));
        }
        Ok(s.mapped(&(Matrix3::identity() * f), &Vector3::zeros()))
    });
    engine.register_fn(
        "scale",
        |s: &mut Solid, x: Dynamic, y: Dynamic, z: Dynamic| -> RResult<Solid> {
            let v = Vector3::new(
                num(&x, "scale", "sx")?,
                num(&y, "scale", "sy")?,
                num(&z, "scale", "sz")?,
            );
            if !v.iter().all(|c| c.is_finite() && *c > 0.0) {
                return fail(format!(
                    "`scale`: factors must be positive and finite, got {:?} (use mirror to flip)",
                    v.as_slice()
                ));
            }
            Ok(s.mapped(&Matrix3::from_diagonal(&v), &Vector3::zeros()))
        },
    );
    engine.register_fn("mirror", |s: &mut Solid, axis: &str| -> RResult<Solid> {
        let d = match axis {
            "x" | "X" => Vector3::new(-1.0, 1.0, 1.0),
            "y" | "Y" => Vector3::new(1.0, -1.0, 1.0),
            "z" | "Z" => Vector3::new(1.0, 1.0, -1.0),
            other => {
                return fail(format!(
                    "`mirror`: axis must be \"x\", \"y\" or \"z\", got \"{other}\""
                ))
            }
        };
        Ok(s.mapped(&Matrix3::from_diagonal(&d), &Vector3::zeros()))
    });
    engine.register_fn("color", |s: &mut Solid, r: Dynamic, g: Dynamic, b: Dynamic| -> RResult<Solid> {
        let c = [num(&r, "color", "r")?, num(&g, "color", "g")?, num(&b, "color", "b")?];
        if c.iter().any(|v| !(0.0..=1.0).contains(v)) {
            return fail(format!("`color`: components must be in 0–1, got {c:?} (for 0–255 values divide by 255)"));
        }
        Ok(Solid { mesh: s.mesh.clone(), color: Some([c[0] as f32, c[1] as f32, c[2] as f32]), surface: None })
    });
    engine.register_fn("color", |s: &mut Solid, c: &str| -> RResult<Solid> {
        Ok(Solid {
            mesh: s.mesh.clone(),
            color: Some(parse_color(c).or_else(fail)?),
            surface: None,
        })
    });

    // Queries.
    engine.register_fn("size", |s: &mut Solid| -> Array {
        to_array(&s.mesh.bounds().extent())
    });
    engine.register_fn("bounds", |s: &mut Solid| -> Map {
        let b = s.mesh.bounds();
        let mut m = Map::new();
        m.insert("min".into(), to_array(&b.min.coords).into());
        m.insert("max".into(), to_array(&b.max.coords).into());
        m.insert("center".into(), to_array(&b.center().coords).into());
        m.insert("size".into(), to_array(&b.extent()).into());
        m
    });
    engine.register_fn("volume", |s: &mut Solid| -> f64 { s.mesh.volume() });
    engine.register_fn("triangle_count", |s: &mut Solid| -> i64 {
        s.mesh.triangles.len() as i64
    });

    // Declarations.
    {
        let st = state.clone();
        engine.register_fn("part", move |name: &str, solid: Solid| -> RResult<()> {
            let mut s = lock(&st);
            if name.trim().is_empty() {
                return fail("`part`: the name must not be empty");
            }
            if s.parts.iter().any(|(n, _)| n == name) {
                return fail(format!(
                    "`part`: a part named `{name}` already exists; part names are unique"
                ));
            }
            if s.parts.len() >= s.limits.max_parts {
                return fail(format!("`part`: more than {} parts", s.limits.max_parts));
            }
            if solid.mesh.is_empty() {
                return fail(format!(
                    "`part`: part `{name}` has no geometry (an empty boolean result?)"
                ));
            }
            s.parts.push((name.to_string(), solid));
            Ok(())
        });
    }
    {
        let st = state.clone();
        engine.register_fn(
            "joint",
            move |ctx: rhai::NativeCallContext, map: Map| -> RResult<()> {
                let j = parse_joint(&map)?;
                lock(&st).joints.push((j, ctx.call_position()));
                Ok(())
            },
        );
    }
    {
        let st = state.clone();
        engine.register_fn(
            "param",
            move |ctx: rhai::NativeCallContext,
                  name: &str,
                  value: Dynamic,
                  min: Dynamic,
                  max: Dynamic|
                  -> RResult<f64> {
                let value = num(&value, "param", "value")?;
                let min = num(&min, "param", "min")?;
                let max = num(&max, "param", "max")?;
                declare_param(&st, name, value, min, max, ctx.call_position())
            },
        );
    }
    // Catch the common mistake of passing a joint as positional arguments.
    engine.register_fn("joint", |_: Dynamic, _: Dynamic| -> RResult<()> {
        fail("`joint` takes one map: joint(#{name: \"hinge\", type: \"revolute\", child: \"lid\", origin: [0, 0, 0], axis: [1, 0, 0], limit: [0, 90]})")
    });
}

/// Records a `param(name, value, min, max)` call and returns the value the script uses.
fn declare_param(
    state: &Shared,
    name: &str,
    value: f64,
    min: f64,
    max: f64,
    pos: Position,
) -> RResult<f64> {
    let mut s = lock(state);
    let valid = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if !valid {
        return fail(format!(
            "`param`: the name \"{name}\" must be letters, digits, `_` or `-` (it is named on the command line)"
        ));
    }
    if s.params.iter().any(|p| p.name == name) {
        return fail(format!(
            "`param`: a parameter named `{name}` already exists; parameter names are unique"
        ));
    }
    if !(value.is_finite() && min.is_finite() && max.is_finite()) {
        return fail(format!(
            "`param` `{name}`: value, min and max must be finite, got {value}, {min}, {max}"
        ));
    }
    if min >= max {
        return fail(format!(
            "`param` `{name}`: min {min} must be under max {max}"
        ));
    }
    if value < min || value > max {
        return fail(format!(
            "`param` `{name}`: the value {value} lies outside its bounds [{min}, {max}]"
        ));
    }
    let used = match s.overrides.get(name) {
        Some(&v) if !(min..=max).contains(&v) || !v.is_finite() => {
            return fail(format!(
                "`param` `{name}`: the value tried, {v}, lies outside its bounds [{min}, {max}]"
            ))
        }
        Some(&v) => v,
        None => value,
    };
    s.params.push(ParamDecl {
        name: name.to_string(),
        default: value,
        value: used,
        min,
        max,
        line: pos.line(),
        column: pos.position(),
    });
    Ok(used)
}

fn make_engine(state: &Shared, meshes: Arc<dyn MeshSource>, limits: &Limits) -> Engine {
    let mut engine = Engine::new();
    engine.set_max_operations(limits.max_operations);
    engine.set_max_call_levels(limits.max_call_depth);
    engine.set_max_expr_depths(128, 64);
    engine.set_max_string_size(limits.max_string_len);
    engine.set_max_array_size(limits.max_array_len);
    engine.set_max_map_size(MAX_MAP_SIZE);
    engine.set_max_variables(10_000);
    engine.set_max_functions(1_000);
    engine.disable_symbol("eval");
    // `f.curry(f)` doubles a function pointer's size at every call (a memory bomb no size
    // limit sees) and nests pointers; scene scripts pass arguments instead.
    engine.disable_symbol("curry");
    let start = Instant::now();
    let budget = limits.max_wall_time;
    engine.on_progress(move |ops| {
        if ops % 4096 == 0 && start.elapsed() > budget {
            Some(Dynamic::from(format!(
                "the script ran longer than {:.1} s",
                budget.as_secs_f64()
            )))
        } else {
            None
        }
    });
    let printed = state.clone();
    engine.on_print(move |s| {
        let mut st = lock(&printed);
        if st.printed.len() < 1000 {
            st.printed.push(s.to_string());
        }
    });
    let debugged = state.clone();
    engine.on_debug(move |s, _, pos| {
        let mut st = lock(&debugged);
        if st.printed.len() < 1000 {
            st.printed.push(format!("[{pos}] {s}"));
        }
    });
    register(&mut engine, state, meshes);
    engine
}

/// The most entries a script's maps hold, nested ones counted.
const MAX_MAP_SIZE: usize = 10_000;

/// The stack a script runs on. Rhai evaluates, measures, clones and frees nested data
/// recursively (one level of an array in an array is a few frames deep), and no engine limit
/// bounds that depth; the size limits do: every level of nesting counts towards
/// `max_array_len` or [`MAX_MAP_SIZE`], and scene scripts have no closures (`no_closure`)
/// and no `curry`, so function pointers hold nothing. This stack holds the deepest nesting
/// the default limits allow with room to spare
/// (`deepest_data_the_limits_allow_is_freed_on_the_script_stack`: in a debug build 8 MiB
/// is too little to free it, 256 MiB too little to compare it, 512 MiB enough). It is
/// reserved address space; only what is used is ever touched.
pub(crate) const SCRIPT_STACK_BYTES: usize = 1 << 30;

pub(crate) fn build(
    source: &str,
    meshes: &dyn MeshSource,
    limits: &Limits,
    overrides: &BTreeMap<String, f64>,
) -> Result<SceneBuild, SceneError> {
    std::thread::scope(|scope| {
        match std::thread::Builder::new()
            .name("scene-script".into())
            .stack_size(SCRIPT_STACK_BYTES)
            .spawn_scoped(scope, || build_here(source, meshes, limits, overrides))
        {
            Ok(handle) => handle.join().unwrap_or_else(|panic| {
                let what = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "no message".into());
                Err(SceneError {
                    kind: SceneErrorKind::Limit,
                    message: format!("the script's evaluation failed inside the engine: {what}"),
                    line: None,
                    column: None,
                    parts_so_far: vec![],
                })
            }),
            // No thread to be had (address space or thread limits): run here, on the
            // caller's stack.
            Err(_) => build_here(source, meshes, limits, overrides),
        }
    })
}

fn build_here(
    source: &str,
    meshes: &dyn MeshSource,
    limits: &Limits,
    overrides: &BTreeMap<String, f64>,
) -> Result<SceneBuild, SceneError> {
    let no_parts = Vec::new;
    if source.len() > limits.max_script_bytes {
        return Err(SceneError {
            kind: SceneErrorKind::Limit,
            message: format!(
                "the script is {} bytes, over the limit of {}",
                source.len(),
                limits.max_script_bytes
            ),
            line: None,
            column: None,
            parts_so_far: no_parts(),
        });
    }
    let state: Shared = Arc::new(Mutex::new(State {
        parts: vec![],
        notes: vec![],
        joints: vec![],
        triangles: 0,
        printed: vec![],
        params: vec![],
        overrides: overrides.clone(),
        limits: limits.clone(),
        deadline: {
            let now = Instant::now();
            now.checked_add(limits.max_wall_time)
                .unwrap_or(now + std::time::Duration::from_secs(365 * 86_400))
        },
    }));
    // The engine's callbacks must own their data: mesh files named by the script are
    // loaded up front through the caller's source.
    let loaded: Arc<dyn MeshSource> = Arc::new(Preloaded::new(source, meshes));
    let engine = make_engine(&state, loaded, limits);
    let ast: AST = engine.compile(source).map_err(|e| {
        let pos = e.position();
        let at_curry = pos
            .line()
            .zip(pos.position())
            .and_then(|(l, c)| source.lines().nth(l.checked_sub(1)?)?.get(c.checked_sub(1)?..))
            .is_some_and(|rest| rest.starts_with("curry"));
        SceneError {
            kind: SceneErrorKind::Syntax,
            message: if at_curry {
                "`curry` is not available in scene scripts; pass every value to `call` (`f.call(a, b)`) or to the function itself".into()
            } else {
                format!("syntax error: {}", e.err_type())
            },
            line: pos.line(),
            column: pos.position(),
            parts_so_far: no_parts(),
        }
    })?;
    let run = engine.run_ast(&ast);
    let st = lock(&state);
    let parts_so_far: Vec<String> = st.parts.iter().map(|(n, _)| n.clone()).collect();
    if let Err(e) = run {
        return Err(explain(*e, parts_so_far, limits));
    }
    if let Some(unknown) = overrides
        .keys()
        .find(|k| !st.params.iter().any(|p| &p.name == *k))
    {
        let declared: Vec<&str> = st.params.iter().map(|p| p.name.as_str()).collect();
        return Err(SceneError {
            kind: SceneErrorKind::UnknownName,
            message: format!(
                "the script declares no parameter `{unknown}`{}",
                if declared.is_empty() {
                    "; declare one with `let w = param(\"width\", 1.0, 0.8, 1.2);`".to_string()
                } else {
                    format!(
                        "; it declares: {}{}",
                        declared.join(", "),
                        did_you_mean(unknown, &declared)
                    )
                }
            ),
            line: None,
            column: None,
            parts_so_far,
        });
    }
    if st.parts.is_empty() {
        return Err(SceneError {
            kind: SceneErrorKind::Model,
            message: "the script defined no parts; declare each piece with part(\"name\", solid)"
                .into(),
            line: None,
            column: None,
            parts_so_far,
        });
    }
    let parts: Vec<Part> = st
        .parts
        .iter()
        .enumerate()
        .map(|(i, (name, solid))| {
            let part = Part::new(
                name.clone(),
                (*solid.mesh).clone(),
                solid.color.unwrap_or(PALETTE[i % PALETTE.len()]),
            );
            match &solid.surface {
                // The surface was read for this mesh, and transforms keep its triangles.
                Some(s) => part.clone().with_surface(s.clone()).unwrap_or(part),
                None => part,
            }
        })
        .collect();
    let names: Vec<String> = parts.iter().map(|p| p.name.clone()).collect();
    let joints: Vec<JointDef> = st.joints.iter().map(|(j, _)| j.clone()).collect();
    let tree = KinematicTree::new(joints, &names).map_err(|e| {
        // Point at the joint() call that declared the offending joint, when we know it.
        let pos = match &e {
            agentstar_geom::GeomError::InvalidJoint { joint, .. } => st
                .joints
                .iter()
                .find(|(j, _)| &j.name == joint)
                .map(|(_, p)| *p),
            _ => None,
        };
        SceneError {
            kind: SceneErrorKind::Model,
            message: e.to_string(),
            line: pos.and_then(|p| p.line()),
            column: pos.and_then(|p| p.position()),
            parts_so_far: parts_so_far.clone(),
        }
    })?;
    let mut warnings = st.notes.clone();
    for j in tree.joints() {
        if let Some((lo, hi)) = j.limit {
            if lo > 0.0 || hi < 0.0 {
                warnings.push(format!("joint `{}`: the rest state 0 lies outside its limit [{lo}, {hi}]; the canonical model should be built at rest", j.name));
            }
        }
    }
    warnings.extend(tree.limit_warnings());
    for (p, part) in parts.iter().enumerate() {
        if !part.watertight && part.mesh.volume().abs() > 1e-9 {
            warnings.push(format!("part `{}` is not watertight (open or self-overlapping surface); silhouettes still render, but it cannot be checked as a solid", names[p]));
        }
    }
    let model = ObjectModel { parts, tree };
    let report = model.canonical_report();
    warnings.extend(report.warnings.iter().cloned());
    let printed = st.printed.clone();
    let params = st.params.clone();
    drop(st);
    Ok(SceneBuild {
        model,
        report,
        warnings,
        printed,
        params,
    })
}

/// Converts a Rhai error into a [`SceneError`] with position and guidance.
fn explain(err: EvalAltResult, parts_so_far: Vec<String>, limits: &Limits) -> SceneError {
    let mut pos = err.position();
    let mut e = err;
    // Whether the innermost function the error happened in is an anonymous one (`|x| …`).
    let mut in_anonymous = false;
    // Unwrap calls into script-defined functions, keeping the innermost known position.
    while let EvalAltResult::ErrorInFunctionCall(name, _, inner, p) = e {
        in_anonymous = name.starts_with("anon$");
        if !p.is_none() {
            pos = p;
        }
        if !inner.position().is_none() {
            pos = inner.position();
        }
        e = *inner;
    }
    if !e.position().is_none() {
        pos = e.position();
    }
    let names = api_names();
    let (kind, message) = match &e {
        EvalAltResult::ErrorFunctionNotFound(sig, _) => {
            let name = sig.split([' ', '(']).next().unwrap_or(sig).trim();
            let name = name.rsplit('.').next().unwrap_or(name);
            if API.iter().any(|a| a.name == name) {
                let all_forms: Vec<&str> = API
                    .iter()
                    .filter(|a| a.name == name)
                    .flat_map(|a| a.forms.iter().copied())
                    .collect();
                (SceneErrorKind::InvalidCall, format!("`{name}` was called with arguments it does not accept ({sig}); valid forms: {}", all_forms.join(" | ")))
            } else {
                (
                    SceneErrorKind::UnknownName,
                    format!("unknown function `{name}`{}", {
                        let s = did_you_mean(name, &names);
                        if s.is_empty() {
                            format!("; the scene API is: {}", names.join(", "))
                        } else {
                            s
                        }
                    }),
                )
            }
        }
        EvalAltResult::ErrorVariableNotFound(v, _) if in_anonymous => (
            SceneErrorKind::UnknownName,
            format!(
                "unknown variable `{v}` inside an anonymous function (`|…| …`): scene scripts have no closures, so an anonymous function sees only its own parameters; pass `{v}` as a parameter or use a `for` loop"
            ),
        ),
        EvalAltResult::ErrorVariableNotFound(v, _) => (
            SceneErrorKind::UnknownName,
            format!(
                "unknown variable `{v}` (declare it with `let {v} = …;` before use; functions and `|x| …` closures see only their own parameters){}",
                did_you_mean(v, &names)
            ),
        ),
        EvalAltResult::ErrorTooManyOperations(_) => (
            SceneErrorKind::Limit,
            format!(
                "the script was stopped after {} operations: an endless loop or far too much work",
                limits.max_operations
            ),
        ),
        EvalAltResult::ErrorTerminated(d, _) => (
            SceneErrorKind::Limit,
            format!("the script was stopped: {d}"),
        ),
        EvalAltResult::ErrorStackOverflow(_) => (
            SceneErrorKind::Limit,
            format!(
                "calls nested deeper than {} levels (unbounded recursion?)",
                limits.max_call_depth
            ),
        ),
        EvalAltResult::ErrorDataTooLarge(what, _) => (
            SceneErrorKind::Limit,
            format!("{what} exceeds the sandbox limit"),
        ),
        EvalAltResult::ErrorRuntime(d, _) => (SceneErrorKind::InvalidCall, d.to_string()),
        EvalAltResult::ErrorMismatchDataType(want, got, _) => (
            SceneErrorKind::InvalidCall,
            format!("type mismatch: expected {want}, got {got}"),
        ),
        other => (
            SceneErrorKind::InvalidCall,
            other
                .to_string()
                .split(" (line")
                .next()
                .unwrap_or_default()
                .to_string(),
        ),
    };
    SceneError {
        kind,
        message,
        line: pos.line(),
        column: pos.position(),
        parts_so_far,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every level of nesting costs an element of an array or an entry of a map, and the
    /// size limits count nested ones: the deepest data a script can build is
    /// `max_array_len + MAX_MAP_SIZE` levels. Rhai clones, prints, compares and frees such
    /// data recursively; all of it fits on the script's stack.
    #[test]
    fn deepest_data_the_limits_allow_is_freed_on_the_script_stack() {
        let depth = Limits::default().max_array_len + MAX_MAP_SIZE;
        std::thread::Builder::new()
            .stack_size(SCRIPT_STACK_BYTES)
            .spawn(move || {
                let mut value = Dynamic::from(1_i64);
                for level in 0..depth {
                    value = if level % 20 == 0 {
                        let mut m = Map::new();
                        m.insert("x".into(), value);
                        Dynamic::from_map(m)
                    } else {
                        Dynamic::from_array(vec![value])
                    };
                }
                let copy = value.clone();
                let text = value.to_string();
                assert!(text.len() > depth);
                // The engine compares nested arrays recursively through its calls.
                let engine = Engine::new();
                let mut scope = rhai::Scope::new();
                scope.push("a", copy);
                scope.push("b", value);
                assert_eq!(
                    engine.eval_with_scope::<bool>(&mut scope, "a == b").ok(),
                    Some(true)
                );
                assert!(engine
                    .eval_with_scope::<bool>(&mut scope, "a.contains(b)")
                    .is_ok());
                drop(scope);
            })
            .expect("thread")
            .join()
            .expect("nested data fits on the script stack");
    }
}
