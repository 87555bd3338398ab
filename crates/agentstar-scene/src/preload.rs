//! Mesh files a script names, loaded before it runs.

use crate::MeshSource;
use agentstar_geom::AppearedMesh;

/// Loads every `mesh("…")` literal of the script up front through the caller's source, so
/// that the engine's callbacks own their data. Paths built at run time fall back to an
/// error that says to use a literal.
pub(crate) struct Preloaded {
    files: Vec<(String, Result<AppearedMesh, String>)>,
}

impl Preloaded {
    pub(crate) fn new(source: &str, meshes: &dyn MeshSource) -> Self {
        let mut files = Vec::new();
        let mut rest = source;
        while let Some(i) = rest.find("mesh(") {
            rest = &rest[i + 5..];
            let t = rest.trim_start();
            if let Some(stripped) = t.strip_prefix('"') {
                if let Some(end) = stripped.find('"') {
                    let path = stripped[..end].to_string();
                    if !files.iter().any(|(p, _)| *p == path) {
                        let loaded = meshes.load(&path);
                        files.push((path, loaded));
                    }
                }
            }
        }
        Preloaded { files }
    }
}

impl MeshSource for Preloaded {
    fn load(&self, path: &str) -> Result<AppearedMesh, String> {
        match self.files.iter().find(|(p, _)| p == path) {
            Some((_, r)) => r.clone(),
            None => Err(format!(
                "`{path}` must be written as a string literal: mesh(\"{path}\")"
            )),
        }
    }
}
