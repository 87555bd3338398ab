//! Writing parts into a glTF binary buffer, shared by the GLB export and the animated GLB:
//! accessors and buffer views, and each part's appearance as glTF materials (one primitive
//! per material, `baseColorFactor` in glTF's linear space, `baseColorTexture` as an
//! embedded PNG with its sampler's wrap modes over `TEXCOORD_0`, vertex colours as
//! `COLOR_0`). Vertices are shared between triangles wherever their corner attributes
//! agree, so a part without seams keeps its welded topology.

use crate::texture::{display_to_linear, texture_png};
use agentstar_geom::{Part, Point3, Texture, WrapMode};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::sync::Arc;

/// A glTF buffer being filled, with the objects that point into it.
#[derive(Default)]
pub(crate) struct GltfBuilder {
    pub bytes: Vec<u8>,
    pub views: Vec<Value>,
    pub accessors: Vec<Value>,
    pub materials: Vec<Value>,
    textures: Vec<Value>,
    images: Vec<Value>,
    samplers: Vec<Value>,
    /// Textures written so far (by identity), with their glTF texture index.
    written: Vec<(Arc<Texture>, usize)>,
}

fn wrap_code(mode: WrapMode) -> u32 {
    match mode {
        WrapMode::Repeat => 10497,
        WrapMode::MirroredRepeat => 33648,
        WrapMode::ClampToEdge => 33071,
    }
}

impl GltfBuilder {
    fn align(&mut self) {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
    }

    /// Appends `data` (rows of `width` floats) as an accessor; returns its index.
    pub fn floats(
        &mut self,
        data: &[f32],
        width: usize,
        kind: &str,
        bounds: bool,
        target: Option<u32>,
    ) -> usize {
        self.align();
        let offset = self.bytes.len();
        for v in data {
            self.bytes.extend_from_slice(&v.to_le_bytes());
        }
        let mut view = json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 4});
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.views.push(view);
        let mut acc = json!({"bufferView": self.views.len() - 1, "componentType": 5126,
                             "count": data.len() / width, "type": kind});
        if bounds {
            let mut min = vec![f32::INFINITY; width];
            let mut max = vec![f32::NEG_INFINITY; width];
            for row in data.chunks_exact(width) {
                for k in 0..width {
                    min[k] = min[k].min(row[k]);
                    max[k] = max[k].max(row[k]);
                }
            }
            acc["min"] = json!(min);
            acc["max"] = json!(max);
        }
        self.accessors.push(acc);
        self.accessors.len() - 1
    }

    /// Appends triangle indices as an accessor; returns its index.
    pub fn indices(&mut self, data: &[u32]) -> usize {
        self.align();
        let offset = self.bytes.len();
        for v in data {
            self.bytes.extend_from_slice(&v.to_le_bytes());
        }
        self.views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 4, "target": 34963}));
        self.accessors.push(
            json!({"bufferView": self.views.len() - 1, "componentType": 5125,
                                   "count": data.len(), "type": "SCALAR"}),
        );
        self.accessors.len() - 1
    }

    /// The glTF texture of `texture`, written once.
    fn texture(&mut self, texture: &Arc<Texture>) -> Result<usize, String> {
        if let Some((_, i)) = self.written.iter().find(|(t, _)| Arc::ptr_eq(t, texture)) {
            return Ok(*i);
        }
        let png = texture_png(texture)?;
        self.align();
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(&png);
        self.views
            .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": png.len()}));
        self.images
            .push(json!({"bufferView": self.views.len() - 1, "mimeType": "image/png"}));
        self.samplers
            .push(json!({"magFilter": 9729, "minFilter": 9729,
            "wrapS": wrap_code(texture.wrap_u), "wrapT": wrap_code(texture.wrap_v)}));
        self.textures
            .push(json!({"sampler": self.samplers.len() - 1, "source": self.images.len() - 1}));
        let index = self.textures.len() - 1;
        self.written.push((texture.clone(), index));
        Ok(index)
    }

    fn material(&mut self, name: &str, color: [f32; 3], texture: Option<&Arc<Texture>>) -> usize {
        let c = color.map(display_to_linear);
        let mut pbr = json!({"baseColorFactor": [c[0], c[1], c[2], 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.6});
        // Encoding an image in memory does not fail; were it to, the material keeps its colour.
        if let Some(index) = texture.and_then(|t| self.texture(t).ok()) {
            pbr["baseColorTexture"] = json!({"index": index});
        }
        self.materials
            .push(json!({"name": name, "pbrMetallicRoughness": pbr}));
        self.materials.len() - 1
    }

    /// The glTF mesh of `part` (positions mapped by `to_gltf`), its materials added.
    pub fn part_mesh(&mut self, part: &Part, to_gltf: impl Fn(&Point3) -> [f32; 3]) -> Value {
        let m = &part.mesh;
        let Some(surface) = &part.surface else {
            let pos: Vec<f32> = m.positions.iter().flat_map(&to_gltf).collect();
            let pa = self.floats(&pos, 3, "VEC3", true, Some(34962));
            let idx: Vec<u32> = m.triangles.iter().flatten().copied().collect();
            let ia = self.indices(&idx);
            let mat = self.material(&part.name, part.color, None);
            return json!({"name": part.name, "primitives": [
                {"attributes": {"POSITION": pa}, "indices": ia, "material": mat}]});
        };
        let mut primitives = Vec::new();
        for (mi, material) in surface.materials().iter().enumerate() {
            let triangles: Vec<usize> = (0..m.triangles.len())
                .filter(|&t| usize::from(surface.triangle_material()[t]) == mi)
                .collect();
            if triangles.is_empty() {
                continue;
            }
            let uvs = surface.corner_uv().filter(|_| material.texture.is_some());
            let colors = surface.corner_color();
            // One vertex per distinct (position, texture coordinates, colour).
            let mut key_to_vertex: HashMap<(u32, [u32; 2], [u32; 3]), u32> = HashMap::new();
            let (mut pos, mut uv, mut col, mut idx) = (vec![], vec![], vec![], vec![]);
            for &t in &triangles {
                for k in 0..3 {
                    let p = m.triangles[t][k];
                    let corner_uv = uvs.map_or([0.0; 2], |u| u[t][k]);
                    let corner_col = colors.map_or([1.0; 3], |c| c[t][k]);
                    let key = (p, corner_uv.map(f32::to_bits), corner_col.map(f32::to_bits));
                    let next = key_to_vertex.len() as u32;
                    let v = *key_to_vertex.entry(key).or_insert_with(|| {
                        pos.extend(to_gltf(&m.positions[p as usize]));
                        uv.extend(corner_uv);
                        col.extend(corner_col.map(display_to_linear));
                        next
                    });
                    idx.push(v);
                }
            }
            let mut attributes =
                json!({"POSITION": self.floats(&pos, 3, "VEC3", true, Some(34962))});
            if uvs.is_some() {
                attributes["TEXCOORD_0"] = json!(self.floats(&uv, 2, "VEC2", false, Some(34962)));
            }
            if colors.is_some() {
                attributes["COLOR_0"] = json!(self.floats(&col, 3, "VEC3", false, Some(34962)));
            }
            let ia = self.indices(&idx);
            let texture = material.texture.as_ref().filter(|_| uvs.is_some());
            let name = format!("{} {}", part.name, material.name);
            let mat = self.material(&name, material.color, texture);
            primitives.push(json!({"attributes": attributes, "indices": ia, "material": mat}));
        }
        json!({"name": part.name, "primitives": primitives})
    }

    /// Puts the buffer's objects into `doc` (those it has), and returns the binary chunk.
    pub fn finish(self, doc: &mut Value) -> Vec<u8> {
        doc["accessors"] = json!(self.accessors);
        doc["bufferViews"] = json!(self.views);
        doc["buffers"] = json!([{"byteLength": self.bytes.len()}]);
        doc["materials"] = json!(self.materials);
        for (key, list) in [
            ("textures", self.textures),
            ("images", self.images),
            ("samplers", self.samplers),
        ] {
            if !list.is_empty() {
                doc[key] = json!(list);
            }
        }
        self.bytes
    }
}
