//! The files a mesh file names beside itself (an OBJ's material library, a texture image)
//! and texture images decoded within bounds.
//!
//! A mesh read for a scene script may only reach files inside the script's directory, as
//! the mesh itself ([`SideFiles::confined`]); a model file a person names directly may name
//! its textures anywhere a relative or absolute path leads ([`SideFiles::beside`]). A side
//! file that cannot be read is a warning naming it, never an error: the part keeps its
//! colour.

use agentstar_geom::Texture;
use std::path::{Component, Path, PathBuf};

/// The longest side of a texture we decode (8192² RGB holds 192 MiB).
pub const TEXTURE_MAX_SIDE: u32 = 8192;
/// The most bytes one texture or material library file may have.
pub const SIDE_FILE_BYTES: u64 = 256 << 20;

/// Where the files a mesh file names are looked up.
#[derive(Debug, Clone)]
pub struct SideFiles {
    dir: Option<PathBuf>,
    /// Set: every file must lie inside this (canonical) directory.
    root: Option<PathBuf>,
}

impl SideFiles {
    /// No side files (a mesh parsed from bytes): every name is a warning.
    pub fn none() -> Self {
        SideFiles {
            dir: None,
            root: None,
        }
    }

    /// Files relative to `dir` (the mesh file's directory), or absolute.
    pub fn beside(dir: impl Into<PathBuf>) -> Self {
        SideFiles {
            dir: Some(dir.into()),
            root: None,
        }
    }

    /// Files relative to `dir` that lie inside `root` (canonical), with no `..` and no
    /// absolute path: the scene sandbox's rule for mesh files.
    pub fn confined(dir: impl Into<PathBuf>, root: impl Into<PathBuf>) -> Self {
        SideFiles {
            dir: Some(dir.into()),
            root: Some(root.into()),
        }
    }

    /// The file `name` (as the mesh file wrote it) under its bound, or why not.
    pub fn read(&self, name: &str) -> Result<(PathBuf, Vec<u8>), String> {
        let Some(dir) = &self.dir else {
            return Err(format!(
                "`{name}` cannot be read: the mesh was not read from a file"
            ));
        };
        // Windows-written files use backslashes.
        let name = name.trim().replace('\\', "/");
        let rel = Path::new(&name);
        let path = dir.join(rel);
        if let Some(root) = &self.root {
            if rel.is_absolute() || rel.components().any(|c| !matches!(c, Component::Normal(_))) {
                return Err(format!(
                    "`{name}` is not a relative path inside the script's directory, so it is not read"
                ));
            }
            let real = path
                .canonicalize()
                .map_err(|e| format!("`{name}` ({}) cannot be opened: {e}", path.display()))?;
            if !real.starts_with(root) {
                return Err(format!(
                    "`{name}` leads outside the script's directory ({}), so it is not read",
                    real.display()
                ));
            }
        }
        let bytes = crate::read_bounded(&path, SIDE_FILE_BYTES).map_err(|e| e.to_string())?;
        Ok((path, bytes))
    }
}

/// Decodes a PNG or JPEG texture named `source`, refusing one over [`TEXTURE_MAX_SIDE`]
/// texels on a side before its pixels are decoded. Alpha is dropped.
pub fn decode_texture(bytes: &[u8], source: &str) -> Result<Texture, String> {
    let format = image::guess_format(bytes)
        .map_err(|e| format!("texture `{source}` is not an image we read: {e}"))?;
    if !matches!(format, image::ImageFormat::Png | image::ImageFormat::Jpeg) {
        return Err(format!(
            "texture `{source}` is {format:?}; textures are PNG or JPEG"
        ));
    }
    if format == image::ImageFormat::Jpeg && !crate::images::jpeg_is_complete(bytes) {
        return Err(format!(
            "texture `{source}` is a truncated JPEG (no end-of-image marker)"
        ));
    }
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(TEXTURE_MAX_SIDE);
    limits.max_image_height = Some(TEXTURE_MAX_SIDE);
    limits.max_alloc = Some(1 << 30);
    reader.limits(limits);
    let img = reader
        .decode()
        .map_err(|e| format!("texture `{source}` does not decode: {e}"))?
        .to_rgb8();
    let (w, h) = img.dimensions();
    Texture::new(source, w, h, img.into_raw()).map_err(|e| e.to_string())
}

/// Reads and decodes the texture file `name` through `files`.
pub fn load_texture(files: &SideFiles, name: &str) -> Result<Texture, String> {
    let (path, bytes) = files.read(name)?;
    decode_texture(&bytes, &path.display().to_string())
}

/// The PNG bytes of a texture (for exports).
pub fn texture_png(texture: &Texture) -> Result<Vec<u8>, String> {
    let img = image::RgbImage::from_raw(texture.width(), texture.height(), texture.rgb().to_vec())
        .ok_or_else(|| format!("texture `{}` has the wrong size", texture.source))?;
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .map_err(|e| format!("texture `{}` does not encode: {e}", texture.source))?;
    Ok(out)
}

/// glTF's linear colour components as the display values agentstar's colours are.
pub fn linear_to_display(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// A display value as glTF's linear colour component.
pub fn display_to_linear(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textures_decode_within_bounds_and_name_what_fails() {
        let img =
            image::RgbImage::from_fn(3, 2, |x, y| image::Rgb([x as u8 * 100, y as u8 * 100, 7]));
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("png");
        let t = decode_texture(&png, "t.png").expect("decodes");
        assert_eq!((t.width(), t.height()), (3, 2));
        assert_eq!(&t.rgb()[3..6], &[100, 0, 7]);
        assert_eq!(
            texture_png(&t).map(|b| decode_texture(&b, "again")
                .map(|u| u == Texture::new("again", 3, 2, t.rgb().to_vec()).expect("t"))),
            Ok(Ok(true))
        );
        let e = decode_texture(b"not an image", "bad.png").expect_err("garbage");
        assert!(e.contains("bad.png"), "{e}");
        // A PNG header that claims 100000 × 1 texels is refused before decoding.
        let mut huge = png.clone();
        huge[16..20].copy_from_slice(&100_000u32.to_be_bytes());
        let e = decode_texture(&huge, "huge.png").expect_err("too wide");
        assert!(e.contains("huge.png"), "{e}");
    }

    #[test]
    fn confined_side_files_stay_inside_the_directory() {
        let dir = tempfile::tempdir().expect("tmp");
        let inner = dir.path().join("scene");
        std::fs::create_dir(&inner).expect("dir");
        std::fs::write(dir.path().join("secret.png"), b"x").expect("write");
        std::fs::write(inner.join("ok.png"), b"x").expect("write");
        let root = inner.canonicalize().expect("root");
        let files = SideFiles::confined(&inner, &root);
        assert!(files.read("ok.png").is_ok());
        for name in ["../secret.png", "/etc/passwd"] {
            let e = files.read(name).expect_err("outside");
            assert!(e.contains(name), "{e}");
        }
        assert!(SideFiles::beside(&inner).read("../secret.png").is_ok());
        assert!(SideFiles::none().read("ok.png").is_err());
    }

    #[test]
    fn colour_space_conversions_invert_each_other() {
        for i in 0..=20 {
            let c = i as f32 / 20.0;
            assert!((linear_to_display(display_to_linear(c)) - c).abs() < 1e-5);
        }
        assert!((linear_to_display(0.214_041) - 0.5).abs() < 1e-3);
    }
}
