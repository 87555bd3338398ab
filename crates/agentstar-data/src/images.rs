//! Images and masks on disk: masks are PNGs where a value above 127 marks the region;
//! frames are RGB JPEG or PNG; outputs are written atomically as PNG.

use crate::{DataError, Result};
use agentstar_render::BitMask;
use image::{GrayImage, RgbImage};
use std::path::Path;

/// Decodes an image file read with a bound, refusing a JPEG without its end-of-image marker
/// (a truncated file, which decoders otherwise fill with grey without complaint).
pub fn decode_image(path: &Path, what: &str) -> Result<image::DynamicImage> {
    let bytes = crate::read_bounded(path, crate::limits::IMAGE_BYTES)?;
    let format = image::guess_format(&bytes)
        .map_err(|e| DataError::invalid(path, format!("cannot read {what}: {e}")))?;
    if format == image::ImageFormat::Jpeg && !jpeg_is_complete(&bytes) {
        return Err(DataError::invalid(
            path,
            format!("cannot read {what}: the JPEG is truncated (no end-of-image marker)"),
        ));
    }
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(&bytes), format);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(16384);
    limits.max_image_height = Some(16384);
    reader.limits(limits);
    reader
        .decode()
        .map_err(|e| DataError::invalid(path, format!("cannot read {what}: {e}")))
}

/// A JPEG ends with the EOI marker `FF D9` (some writers pad a few bytes after it).
fn jpeg_is_complete(bytes: &[u8]) -> bool {
    let tail = &bytes[bytes.len().saturating_sub(64)..];
    tail.windows(2).any(|w| w == [0xFF, 0xD9])
}

pub fn load_rgb(path: &Path) -> Result<RgbImage> {
    Ok(decode_image(path, "image")?.to_rgb8())
}

/// Reads a binary mask (> 127 = inside), any PNG colour type (luma of the first channel).
pub fn load_mask(path: &Path) -> Result<BitMask> {
    let g = decode_image(path, "mask")?.to_luma8();
    Ok(BitMask::from_fn(g.width(), g.height(), |x, y| {
        g.get_pixel(x, y)[0] > 127
    }))
}

/// Image size without decoding the pixels (only regular files within the image limit).
pub fn image_size(path: &Path) -> Result<(u32, u32)> {
    let meta = std::fs::metadata(path).map_err(|e| DataError::io(path, e))?;
    if !meta.is_file() {
        return Err(DataError::invalid(
            path,
            "cannot read image: not a regular file",
        ));
    }
    if meta.len() > crate::limits::IMAGE_BYTES {
        return Err(DataError::invalid(
            path,
            format!(
                "cannot read image: larger than the limit of {} MiB",
                crate::limits::IMAGE_BYTES >> 20
            ),
        ));
    }
    image::image_dimensions(path)
        .map_err(|e| DataError::invalid(path, format!("cannot read image: {e}")))
}

pub fn mask_to_gray(mask: &BitMask) -> GrayImage {
    GrayImage::from_fn(mask.width(), mask.height(), |x, y| {
        image::Luma([if mask.get(x, y) { 255 } else { 0 }])
    })
}

fn encode_png(
    write: impl FnOnce(&mut std::io::Cursor<Vec<u8>>) -> image::ImageResult<()>,
    path: &Path,
) -> Result<Vec<u8>> {
    let mut buf = std::io::Cursor::new(Vec::new());
    write(&mut buf).map_err(|e| DataError::invalid(path, format!("cannot encode PNG: {e}")))?;
    Ok(buf.into_inner())
}

pub fn save_png_rgb(img: &RgbImage, path: &Path) -> Result<()> {
    let bytes = encode_png(|b| img.write_to(b, image::ImageFormat::Png), path)?;
    crate::atomic::write_atomic(path, &bytes)
}

pub fn save_png_rgba(img: &image::RgbaImage, path: &Path) -> Result<()> {
    let bytes = encode_png(|b| img.write_to(b, image::ImageFormat::Png), path)?;
    crate::atomic::write_atomic(path, &bytes)
}

pub fn save_png_gray(img: &GrayImage, path: &Path) -> Result<()> {
    let bytes = encode_png(|b| img.write_to(b, image::ImageFormat::Png), path)?;
    crate::atomic::write_atomic(path, &bytes)
}
