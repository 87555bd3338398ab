//! Binary glTF (GLB) read into one mesh per root node with its appearance: each
//! primitive's material (`baseColorFactor`, `baseColorTexture` through its
//! `TEXCOORD_n` and its sampler's wrap modes) and `COLOR_0` vertex colours. glTF's linear
//! colours become the display values agentstar's colours are. Textures are PNG or JPEG,
//! embedded in the binary chunk or files beside the GLB ([`SideFiles`]); one that cannot be
//! read is a warning naming it, and its primitives keep the material's colour.

use crate::texture::{decode_texture, linear_to_display, SideFiles};
use agentstar_geom::{
    AppearedMesh, Material, Matrix4, Point3, SurfaceAppearance, Texture, TriMesh, WrapMode,
};
use std::collections::BTreeMap;
use std::sync::Arc;

/// Reads a binary glTF: one mesh per root node (its subtree merged), named after the node,
/// converted to the canonical Z-up frame. Sorted as in the file.
pub fn parse_glb(bytes: &[u8]) -> Result<Vec<(String, TriMesh)>, String> {
    Ok(parse_glb_appearance(bytes, &SideFiles::none())?
        .into_iter()
        .map(|(n, m)| (n, m.mesh))
        .collect())
}

fn y_up_to_z_up() -> Matrix4 {
    Matrix4::new(
        1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    )
}

/// [`parse_glb`] with each root node's appearance; texture files are looked up in `files`.
pub fn parse_glb_appearance(
    bytes: &[u8],
    files: &SideFiles,
) -> Result<Vec<(String, AppearedMesh)>, String> {
    parse_glb_from(bytes, y_up_to_z_up(), files)
}

/// Reads a binary glTF as [`parse_glb`] does but keeps the file's own coordinates (no Y-up
/// to Z-up turn): for datasets whose poses refer to the model as stored (HOT3D).
pub fn parse_glb_file_frame(bytes: &[u8]) -> Result<Vec<(String, TriMesh)>, String> {
    Ok(
        parse_glb_from(bytes, Matrix4::identity(), &SideFiles::none())?
            .into_iter()
            .map(|(n, m)| (n, m.mesh))
            .collect(),
    )
}

/// Checks an accessor before the `gltf` reader touches it (the reader indexes and asserts on
/// what the file claims): its buffer view lies inside the binary chunk, its elements fit
/// in the view, and its type is what we read.
fn check_accessor(
    acc: &gltf::Accessor,
    blob_len: usize,
    what: &str,
    dims: gltf::accessor::Dimensions,
    types: &[gltf::accessor::DataType],
) -> Result<(), String> {
    let bad = |why: String| Err(format!("accessor {} ({what}): {why}", acc.index()));
    if acc.sparse().is_some() {
        return bad("sparse accessors are not supported".into());
    }
    if acc.dimensions() != dims || !types.contains(&acc.data_type()) {
        return bad(format!(
            "type {:?} {:?} is not the expected {dims:?}",
            acc.dimensions(),
            acc.data_type()
        ));
    }
    let Some(view) = acc.view() else {
        return bad("it has no buffer view".into());
    };
    let buffer = view.buffer();
    if !matches!(buffer.source(), gltf::buffer::Source::Bin) {
        return bad("its buffer is not the GLB's binary chunk".into());
    }
    let view_end = view.offset().checked_add(view.length());
    if buffer.length() > blob_len || view_end.is_none_or(|e| e > buffer.length()) {
        return bad("its buffer view lies outside the binary chunk".into());
    }
    let elem = acc.size();
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return bad(format!(
            "byte stride {stride} is smaller than an element ({elem} bytes)"
        ));
    }
    if acc.count() > 0 {
        let last = (acc.count() - 1)
            .checked_mul(stride)
            .and_then(|v| v.checked_add(acc.offset()))
            .and_then(|v| v.checked_add(elem));
        if last.is_none_or(|l| l > view.length()) {
            return bad(format!(
                "{} elements do not fit in its buffer view of {} bytes",
                acc.count(),
                view.length()
            ));
        }
    }
    Ok(())
}

/// Checks what the `gltf` crate (1.4) trusts and panics on: the GLB header and chunk
/// lengths, and the accessor indices that its validation looks up unchecked.
fn precheck_glb(bytes: &[u8]) -> Result<Vec<String>, String> {
    let word = |at: usize| -> Option<u32> {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    if bytes.get(..4) != Some(b"glTF") {
        return Err("not a GLB file (no `glTF` magic)".into());
    }
    let total = word(8).ok_or("the GLB header is truncated")? as usize;
    if total < 20 || total > bytes.len() {
        return Err(format!(
            "the GLB header gives a length of {total} bytes but the file has {}",
            bytes.len()
        ));
    }
    let json_len = word(12).ok_or("the GLB JSON chunk is truncated")? as usize;
    if word(16) != Some(0x4E4F_534A) || 20usize.saturating_add(json_len) > total {
        return Err("the GLB JSON chunk is malformed".into());
    }
    let json_end = 20 + json_len;
    let bin_at = json_end.div_ceil(4) * 4;
    if bin_at + 8 <= total {
        let bin_len = word(bin_at).unwrap_or(u32::MAX) as usize;
        if (bin_at + 8).saturating_add(bin_len) > total {
            return Err("the GLB binary chunk runs past the end of the file".into());
        }
    }
    let json: serde_json::Value = serde_json::from_slice(&bytes[20..json_end])
        .map_err(|e| format!("the GLB JSON chunk is not JSON: {e}"))?;
    let accessors = json["accessors"].as_array().map_or(0, Vec::len);
    for mesh in json["meshes"].as_array().into_iter().flatten() {
        for prim in mesh["primitives"].as_array().into_iter().flatten() {
            let refs = prim["attributes"]
                .as_object()
                .into_iter()
                .flat_map(|a| a.values())
                .chain(std::iter::once(&prim["indices"]))
                .filter(|v| !v.is_null());
            for r in refs {
                if r.as_u64().is_none_or(|i| i as usize >= accessors) {
                    return Err(format!(
                        "a mesh primitive refers to accessor {r}, but there are {accessors}"
                    ));
                }
            }
        }
    }
    // Extensions change what a file shows (a texture transform, another material model);
    // none is read, so each one the file declares is named rather than silently ignored.
    let unread: Vec<&str> = json["extensionsUsed"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|e| e.as_str())
        .collect();
    Ok(if unread.is_empty() {
        vec![]
    } else {
        vec![format!(
            "the file uses glTF extensions that are not read ({}); what they change (texture transforms, other materials) is not drawn",
            unread.join(", ")
        )]
    })
}

fn parse_glb_from(
    bytes: &[u8],
    root_from_file: Matrix4,
    files: &SideFiles,
) -> Result<Vec<(String, AppearedMesh)>, String> {
    let file_warnings = precheck_glb(bytes).map_err(|e| format!("not a valid GLB file: {e}"))?;
    // The prechecks cover the panics we know of in `gltf`; a reader bug we do not know of
    // is still an error about this file rather than a crash.
    let gltf = std::panic::catch_unwind(|| gltf::Gltf::from_slice(bytes))
        .map_err(|_| "not a valid GLB file: the glTF reader failed on it".to_string())?
        .map_err(|e| format!("not a valid GLB file: {e}"))?;
    let blob = gltf.blob.as_deref();
    let blob_len = blob.map_or(0, <[u8]>::len);
    let scene = gltf
        .default_scene()
        .or_else(|| gltf.scenes().next())
        .ok_or("the GLB file has no scene")?;
    let mut parts = Vec::new();
    let mut textures = TextureCache::default();
    for (i, root) in scene.nodes().enumerate() {
        let mut mesh = TriMesh::default();
        let mut look = Looks::default();
        let mut stack = vec![(root.clone(), root_from_file, 0usize)];
        let mut visited = 0usize;
        while let Some((node, parent, depth)) = stack.pop() {
            // A node graph with a cycle (invalid glTF) would never end.
            visited += 1;
            if depth > 256 || visited > 1_000_000 {
                return Err("the node hierarchy is cyclic or deeper than 256 levels".into());
            }
            let local = Matrix4::from_fn(|r, c| node.transform().matrix()[c][r] as f64);
            let world = parent * local;
            if let Some(m) = node.mesh() {
                for prim in m.primitives() {
                    if prim.mode() != gltf::mesh::Mode::Triangles {
                        continue;
                    }
                    use gltf::accessor::{DataType, Dimensions};
                    if let Some(acc) = prim.get(&gltf::Semantic::Positions) {
                        check_accessor(
                            &acc,
                            blob_len,
                            "positions",
                            Dimensions::Vec3,
                            &[DataType::F32],
                        )?;
                    }
                    if let Some(acc) = prim.indices() {
                        check_accessor(
                            &acc,
                            blob_len,
                            "indices",
                            Dimensions::Scalar,
                            &[DataType::U8, DataType::U16, DataType::U32],
                        )?;
                    }
                    let uv_set = prim
                        .material()
                        .pbr_metallic_roughness()
                        .base_color_texture()
                        .map(|t| t.tex_coord());
                    let uv_acc = uv_set.and_then(|set| prim.get(&gltf::Semantic::TexCoords(set)));
                    if let Some(acc) = &uv_acc {
                        check_accessor(
                            acc,
                            blob_len,
                            "texture coordinates",
                            Dimensions::Vec2,
                            &[DataType::F32, DataType::U8, DataType::U16],
                        )?;
                    }
                    let color_acc = prim.get(&gltf::Semantic::Colors(0));
                    if let Some(acc) = &color_acc {
                        let dims = if acc.dimensions() == Dimensions::Vec4 {
                            Dimensions::Vec4
                        } else {
                            Dimensions::Vec3
                        };
                        check_accessor(
                            acc,
                            blob_len,
                            "vertex colours",
                            dims,
                            &[DataType::F32, DataType::U8, DataType::U16],
                        )?;
                    }
                    let reader = prim.reader(|b| match b.source() {
                        gltf::buffer::Source::Bin => blob,
                        gltf::buffer::Source::Uri(_) => None,
                    });
                    let Some(positions) = reader.read_positions() else {
                        continue;
                    };
                    let base = mesh.positions.len() as u32;
                    let first_triangle = mesh.triangles.len();
                    let pts: Vec<Point3> = positions
                        .map(|p| {
                            world.transform_point(&Point3::new(
                                p[0] as f64,
                                p[1] as f64,
                                p[2] as f64,
                            ))
                        })
                        .collect();
                    let count = pts.len() as u32;
                    mesh.positions.extend(pts);
                    match reader.read_indices() {
                        Some(ind) => {
                            let ind: Vec<u32> = ind.into_u32().collect();
                            mesh.triangles.extend(ind.chunks_exact(3).map(|t| {
                                // Out-of-range indices are reported by `check`.
                                [
                                    t[0].saturating_add(base),
                                    t[1].saturating_add(base),
                                    t[2].saturating_add(base),
                                ]
                            }));
                        }
                        None => mesh.triangles.extend(
                            (0..count / 3)
                                .map(|k| [base + 3 * k, base + 3 * k + 1, base + 3 * k + 2]),
                        ),
                    }
                    let uvs: Option<Vec<[f32; 2]>> = match (uv_set, &uv_acc) {
                        (Some(set), Some(_)) => {
                            reader.read_tex_coords(set).map(|t| t.into_f32().collect())
                        }
                        _ => None,
                    };
                    let colors: Option<Vec<[f32; 3]>> = color_acc.as_ref().and_then(|_| {
                        reader
                            .read_colors(0)
                            .map(|c| c.into_rgb_f32().map(|c| c.map(linear_to_display)).collect())
                    });
                    let material = textures.material(
                        &prim.material(),
                        uvs.is_some(),
                        blob,
                        files,
                        &mut look.warnings,
                    );
                    look.add(
                        &mesh.triangles[first_triangle..],
                        base,
                        material,
                        uvs.as_deref(),
                        colors.as_deref(),
                    )?;
                    if world.fixed_view::<3, 3>(0, 0).determinant() < 0.0 {
                        for t in mesh.triangles.iter_mut().skip(first_triangle) {
                            t.swap(1, 2);
                        }
                        look.swap_since(first_triangle);
                    }
                }
            }
            for c in node.children() {
                stack.push((c, world, depth + 1));
            }
        }
        if !mesh.triangles.is_empty() {
            let (surface, warnings) = look.finish()?;
            parts.push((
                root.name()
                    .map(str::to_string)
                    .unwrap_or_else(|| format!("node{i}")),
                AppearedMesh {
                    mesh,
                    surface,
                    warnings,
                },
            ));
        }
    }
    if let Some((_, first)) = parts.first_mut() {
        first.warnings.extend(file_warnings);
    }
    if parts.is_empty() {
        return Err(
            "the GLB file holds no triangle geometry (external buffers are not supported)".into(),
        );
    }
    Ok(parts)
}

/// The materials of one glTF file, each read once: its textures shared by every part that
/// uses them.
#[derive(Default)]
struct TextureCache {
    textures: BTreeMap<usize, Option<Arc<Texture>>>,
}

/// The glTF sampler wrap mode as ours.
fn wrap_mode(mode: gltf::texture::WrappingMode) -> WrapMode {
    match mode {
        gltf::texture::WrappingMode::ClampToEdge => WrapMode::ClampToEdge,
        gltf::texture::WrappingMode::MirroredRepeat => WrapMode::MirroredRepeat,
        gltf::texture::WrappingMode::Repeat => WrapMode::Repeat,
    }
}

impl TextureCache {
    /// The material of a primitive: its base colour factor, and its texture when the
    /// primitive has the texture coordinates it names and the image reads.
    fn material(
        &mut self,
        m: &gltf::Material,
        has_uvs: bool,
        blob: Option<&[u8]>,
        files: &SideFiles,
        warnings: &mut Vec<String>,
    ) -> Material {
        let pbr = m.pbr_metallic_roughness();
        let f = pbr.base_color_factor();
        let name = m
            .name()
            .map(str::to_string)
            .or_else(|| m.index().map(|i| format!("material {i}")))
            .unwrap_or_else(|| "default material".into());
        let mut out = Material {
            name: name.clone(),
            color: [f[0], f[1], f[2]].map(linear_to_display),
            texture: None,
        };
        let Some(info) = pbr.base_color_texture() else {
            return out;
        };
        if !has_uvs {
            warnings.push(format!(
                "material `{name}` has a base colour texture but its primitive has no TEXCOORD_{}; it keeps the material's colour",
                info.tex_coord()
            ));
            return out;
        }
        let tex = info.texture();
        let index = tex.index();
        let entry = self.textures.entry(index).or_insert_with(|| {
            let read = read_image(&tex.source(), blob, files).map(|t| {
                let s = tex.sampler();
                Arc::new(t.with_wrap(wrap_mode(s.wrap_s()), wrap_mode(s.wrap_t())))
            });
            read.map_err(|e| {
                warnings.push(format!(
                    "material `{name}`: {e}; the part keeps the material's colour"
                ))
            })
            .ok()
        });
        out.texture = entry.clone();
        out
    }
}

/// The texture an image names: bytes in the binary chunk, or a file beside the GLB.
fn read_image(
    image: &gltf::image::Image,
    blob: Option<&[u8]>,
    files: &SideFiles,
) -> Result<Texture, String> {
    let what = image
        .name()
        .map(|n| format!("image `{n}`"))
        .unwrap_or_else(|| format!("image {}", image.index()));
    match image.source() {
        gltf::image::Source::View { view, .. } => {
            let blob = blob.ok_or_else(|| format!("{what}: the GLB has no binary chunk"))?;
            if !matches!(view.buffer().source(), gltf::buffer::Source::Bin) {
                return Err(format!("{what}: its buffer is not the GLB's binary chunk"));
            }
            let bytes = view
                .offset()
                .checked_add(view.length())
                .and_then(|end| blob.get(view.offset()..end))
                .ok_or_else(|| format!("{what}: its buffer view lies outside the binary chunk"))?;
            decode_texture(bytes, &what)
        }
        gltf::image::Source::Uri { uri, .. } => {
            if uri.starts_with("data:") {
                return Err(format!(
                    "{what} is a data URI, which is not read (embed it in the binary chunk)"
                ));
            }
            let (path, bytes) = files.read(&uri.replace("%20", " "))?;
            decode_texture(&bytes, &path.display().to_string())
        }
    }
}

/// Appearance gathered over one root node's primitives, triangle by triangle.
#[derive(Default)]
struct Looks {
    materials: Vec<Material>,
    triangle_material: Vec<u16>,
    corner_uv: Vec<[[f32; 2]; 3]>,
    corner_color: Vec<[[f32; 3]; 3]>,
    any_uv: bool,
    any_color: bool,
    warnings: Vec<String>,
}

impl Looks {
    /// The triangles of one primitive (indices offset by `base`) with its material and
    /// per-vertex attributes.
    fn add(
        &mut self,
        triangles: &[[u32; 3]],
        base: u32,
        material: Material,
        uvs: Option<&[[f32; 2]]>,
        colors: Option<&[[f32; 3]]>,
    ) -> Result<(), String> {
        let index = match self.materials.iter().position(|m| *m == material) {
            Some(i) => i,
            None => {
                if self.materials.len() >= usize::from(u16::MAX) {
                    return Err("more than 65535 materials in one node".into());
                }
                self.materials.push(material);
                self.materials.len() - 1
            }
        };
        self.any_uv |= uvs.is_some();
        self.any_color |= colors.is_some();
        for t in triangles {
            let local = t.map(|i| i.wrapping_sub(base) as usize);
            self.triangle_material.push(index as u16);
            self.corner_uv
                .push(local.map(|i| uvs.and_then(|u| u.get(i)).copied().unwrap_or([0.0; 2])));
            self.corner_color
                .push(local.map(|i| colors.and_then(|c| c.get(i)).copied().unwrap_or([1.0; 3])));
        }
        Ok(())
    }

    fn swap_since(&mut self, first: usize) {
        self.corner_uv
            .iter_mut()
            .skip(first)
            .for_each(|t| t.swap(1, 2));
        self.corner_color
            .iter_mut()
            .skip(first)
            .for_each(|t| t.swap(1, 2));
    }

    /// The node's surface, `None` when it is one plain white default material (the file
    /// gave it no appearance).
    fn finish(self) -> Result<(Option<Arc<SurfaceAppearance>>, Vec<String>), String> {
        let plain_default = self.materials.len() == 1
            && self.materials[0].texture.is_none()
            && self.materials[0].color == [1.0; 3]
            && !self.any_color;
        if plain_default || self.materials.is_empty() {
            return Ok((None, self.warnings));
        }
        let any_texture = self.materials.iter().any(|m| m.texture.is_some());
        let surface = SurfaceAppearance::new(
            self.materials,
            self.triangle_material,
            (self.any_uv && any_texture).then_some(self.corner_uv),
            self.any_color.then_some(self.corner_color),
        )
        .map_err(|e| e.to_string())?;
        Ok((Some(Arc::new(surface)), self.warnings))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::primitives::cuboid;
    use agentstar_geom::{KinematicTree, ObjectModel, Part};

    /// A one-box GLB with `edit` applied to its JSON.
    fn glb_with(edit: impl Fn(&mut serde_json::Value)) -> Vec<u8> {
        let model = ObjectModel {
            parts: vec![Part::new(
                "box",
                cuboid(1.0, 1.0, 1.0).expect("box"),
                [0.2, 0.4, 0.6],
            )],
            tree: KinematicTree::rigid(1),
        };
        let bytes = crate::export::glb_bytes(&model);
        let json_len = u32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]) as usize;
        let mut doc: serde_json::Value =
            serde_json::from_slice(&bytes[20..20 + json_len]).expect("json");
        let bin_at = 20 + json_len;
        let bin_len = u32::from_le_bytes([
            bytes[bin_at],
            bytes[bin_at + 1],
            bytes[bin_at + 2],
            bytes[bin_at + 3],
        ]) as usize;
        let bin = bytes[bin_at + 8..bin_at + 8 + bin_len].to_vec();
        edit(&mut doc);
        crate::export::glb_container(&doc, bin)
    }

    #[test]
    fn a_plain_materials_colour_round_trips_and_unread_extensions_are_named() {
        let parts = parse_glb_appearance(&glb_with(|_| {}), &SideFiles::none()).expect("glb");
        let surface = parts[0].1.surface.as_ref().expect("a material");
        let c = surface.materials()[0].color;
        assert!(
            (0..3).all(|i| (c[i] - [0.2, 0.4, 0.6][i]).abs() < 1e-5),
            "{c:?}"
        );
        assert!(parts[0].1.warnings.is_empty());
        let with_ext = glb_with(|d| {
            d["extensionsUsed"] = serde_json::json!(["KHR_texture_transform"]);
        });
        let parts = parse_glb_appearance(&with_ext, &SideFiles::none()).expect("glb");
        assert!(
            parts[0]
                .1
                .warnings
                .iter()
                .any(|w| w.contains("KHR_texture_transform")),
            "{:?}",
            parts[0].1.warnings
        );
    }

    #[test]
    fn a_texture_on_a_primitive_without_its_coordinates_is_named_and_dropped() {
        // A base colour texture on the box, whose primitive has no texture coordinates.
        let glb = glb_with(|d| {
            let views = d["bufferViews"].as_array_mut().expect("views");
            views.push(serde_json::json!({"buffer": 0, "byteOffset": 0, "byteLength": 8}));
            let last = views.len() - 1;
            d["images"] = serde_json::json!([{"bufferView": last, "mimeType": "image/png"}]);
            d["textures"] = serde_json::json!([{"source": 0}]);
            d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] =
                serde_json::json!({"index": 0});
        });
        let parts = parse_glb_appearance(&glb, &SideFiles::none()).expect("still reads");
        // The box has no TEXCOORD_0: the texture is named and dropped.
        assert!(
            parts[0].1.warnings.iter().any(|w| w.contains("TEXCOORD_0")),
            "{:?}",
            parts[0].1.warnings
        );
    }
}
