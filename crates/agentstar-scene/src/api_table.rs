//! The table of every function a scene script can call: its forms and what it does, for
//! error messages and `docs/scene.md`'s generated reference.

/// One entry of the scene API, for error messages and generated documentation.
#[derive(Debug, Clone, Copy)]
pub struct ApiEntry {
    pub name: &'static str,
    pub forms: &'static [&'static str],
    pub doc: &'static str,
}

/// Every function a script can call. Units: canonical (longest side about 1); angles in degrees.
pub const API: &[ApiEntry] = &[
    ApiEntry { name: "box", forms: &["box(size_x, size_y, size_z)", "box(size_x, size_y, size_z, bevel)", "box(size_x, size_y, size_z, bevel, segments)"], doc: "Axis-aligned box centred at the origin with full extents; `bevel` rounds the edges with that radius (segments = 1 chamfers)." },
    ApiEntry { name: "cylinder", forms: &["cylinder(radius, height)", "cylinder(radius, height, segments)"], doc: "Cylinder along Z centred at the origin (default 48 segments)." },
    ApiEntry { name: "sector", forms: &["sector(radius, height, angle_deg)", "sector(radius, height, angle_deg, segments)"], doc: "Pie-slice prism along Z centred at the origin, the sector from −angle/2 to +angle/2 about +X (0 < angle < 360; default 48 segments); with intersection it keeps part of a turn: a label over 195° of a side is intersection(sleeve, sector(1, 1, 195))." },
    ApiEntry { name: "cone", forms: &["cone(radius_bottom, radius_top, height)", "cone(radius_bottom, radius_top, height, segments)"], doc: "Truncated cone along Z, bottom at z = −height/2; a radius of 0 makes a point." },
    ApiEntry { name: "sphere", forms: &["sphere(radius)", "sphere(radius, segments, rings)"], doc: "UV sphere centred at the origin, poles on Z (default 32 × 16)." },
    ApiEntry { name: "ico_sphere", forms: &["ico_sphere(radius)", "ico_sphere(radius, subdivisions)"], doc: "Subdivided icosahedron (default 2 subdivisions, at most 6)." },
    ApiEntry { name: "torus", forms: &["torus(major_radius, minor_radius)", "torus(major_radius, minor_radius, segments, minor_segments)"], doc: "Ring around Z in the XY plane: tube centre at major_radius, tube radius minor_radius." },
    ApiEntry { name: "capsule", forms: &["capsule(radius, length)", "capsule(radius, length, segments)"], doc: "Cylinder of `length` along Z capped by hemispheres (total height length + 2·radius)." },
    ApiEntry { name: "plane", forms: &["plane(size_x, size_y)"], doc: "Zero-thickness rectangle in the XY plane, visible from both sides (prefer a thin box for solids)." },
    ApiEntry { name: "disc", forms: &["disc(radius)", "disc(radius, segments)"], doc: "Zero-thickness disc in the XY plane, visible from both sides." },
    ApiEntry { name: "wedge", forms: &["wedge(size_x, size_y, size_z)"], doc: "Ramp: footprint size_x × size_y, full height at −Y sloping to zero at +Y." },
    ApiEntry { name: "hull", forms: &["hull(points)"], doc: "Convex hull of [[x, y, z], …] (at least 4 points, not all coplanar)." },
    ApiEntry { name: "extrude", forms: &["extrude(outline, height)", "extrude(outline, holes, height)"], doc: "Prism from a 2-D polygon [[x, y], …] in XY (holes: a list of polygons), extruded along Z, centred on z = 0." },
    ApiEntry { name: "lathe", forms: &["lathe(profile)", "lathe(profile, segments)"], doc: "Revolves [[radius, z], …] about Z; radius 0 makes a pole; ends off the axis get flat caps; a closed loop (first = last) makes a ring." },
    ApiEntry { name: "mesh", forms: &["mesh(path)"], doc: "Loads an OBJ, STL, PLY or GLB file that sits beside the script (no other paths), with its materials, texture and vertex colours (the files they name must sit beside it too)." },
    ApiEntry { name: "union", forms: &["union(a, b)", "a + b"], doc: "Boolean union (solids only; never unite parts that move relative to each other)." },
    ApiEntry { name: "union_all", forms: &["union_all([a, b, …])"], doc: "Boolean union of a list of solids." },
    ApiEntry { name: "difference", forms: &["difference(a, b)", "a - b"], doc: "Boolean difference: a with b removed. The cutter should stick out through every surface it cuts." },
    ApiEntry { name: "intersection", forms: &["intersection(a, b)"], doc: "Boolean intersection." },
    ApiEntry { name: "translate", forms: &["s.translate(x, y, z)", "s.translate([x, y, z])"], doc: "Moves a solid." },
    ApiEntry { name: "rotate", forms: &["s.rotate([ax, ay, az], angle_deg)"], doc: "Rotates about an axis through the origin, right-handed, degrees." },
    ApiEntry { name: "rotate_x", forms: &["s.rotate_x(angle_deg)"], doc: "Rotates about +X (degrees)." },
    ApiEntry { name: "rotate_y", forms: &["s.rotate_y(angle_deg)"], doc: "Rotates about +Y (degrees)." },
    ApiEntry { name: "rotate_z", forms: &["s.rotate_z(angle_deg)"], doc: "Rotates about +Z (degrees)." },
    ApiEntry { name: "rotate_euler", forms: &["s.rotate_euler(x_deg, y_deg, z_deg)"], doc: "Euler XYZ as in Blender: about X, then Y, then Z (fixed axes)." },
    ApiEntry { name: "scale", forms: &["s.scale(factor)", "s.scale(sx, sy, sz)"], doc: "Scales about the origin (factors > 0; use mirror to flip)." },
    ApiEntry { name: "mirror", forms: &["s.mirror(\"x\")"], doc: "Mirrors across the plane through the origin normal to x, y or z." },
    ApiEntry { name: "color", forms: &["s.color(r, g, b)", "s.color(\"#rrggbb\")", "s.color(\"red\")"], doc: "Colour of the part (0–1 components, hex, or a name)." },
    ApiEntry { name: "size", forms: &["s.size()"], doc: "Bounding-box extents [x, y, z]." },
    ApiEntry { name: "bounds", forms: &["s.bounds()"], doc: "#{min: [..], max: [..], center: [..], size: [..]} of the bounding box." },
    ApiEntry { name: "volume", forms: &["s.volume()"], doc: "Enclosed volume." },
    ApiEntry { name: "triangle_count", forms: &["s.triangle_count()"], doc: "Number of triangles." },
    ApiEntry { name: "part", forms: &["part(name, solid)"], doc: "Declares a named part (the unit that joints move and exports name)." },
    ApiEntry { name: "param", forms: &["param(name, value, min, max)"], doc: "A named shape parameter with its bounds: returns `value` (or the value `fit_shape` is trying); `agentstar fit-shape --params name` fits it within [min, max] against the committed poses and writes the result back as the new `value` (keep it a number literal)." },
    ApiEntry { name: "joint", forms: &["joint(#{name, type, child, origin, axis, limit, parent})"], doc: "Declares a joint: type revolute (limit in degrees), continuous (no limit), prismatic (limit in canonical units) or fixed; child is a part name or a list; origin and axis in the canonical rest frame; parent names another joint for chains." },
];

/// The API reference as Markdown (one row per function), the source of `docs/scene.md`'s
/// reference section so that the docs cannot drift from what is registered.
pub fn api_markdown() -> String {
    let mut s = String::from("| function | forms | what it does |\n|---|---|---|\n");
    for e in API {
        let forms: Vec<String> = e.forms.iter().map(|f| format!("`{f}`")).collect();
        s.push_str(&format!(
            "| `{}` | {} | {} |\n",
            e.name,
            forms.join("<br>"),
            e.doc
        ));
    }
    s
}

/// Names of every API function (sorted, unique).
pub fn api_names() -> Vec<&'static str> {
    let mut v: Vec<&str> = API.iter().map(|e| e.name).collect();
    v.sort_unstable();
    v.dedup();
    v
}
