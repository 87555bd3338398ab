//! Images and masks on disk: masks are PNGs where a value above 127 marks the region;
//! frames are RGB JPEG or PNG; outputs are written atomically as PNG.

use crate::{DataError, Result};
use agentstar_render::BitMask;
use image::{GrayImage, RgbImage};
use std::path::Path;

pub fn load_rgb(path: &Path) -> Result<RgbImage> {
    let img = image::open(path)
        .map_err(|e| DataError::invalid(path, format!("cannot read image: {e}")))?;
    Ok(img.to_rgb8())
}

/// Reads a binary mask (> 127 = inside), any PNG colour type (luma of the first channel).
pub fn load_mask(path: &Path) -> Result<BitMask> {
    let img = image::open(path)
        .map_err(|e| DataError::invalid(path, format!("cannot read mask: {e}")))?;
    let g = img.to_luma8();
    Ok(BitMask::from_fn(g.width(), g.height(), |x, y| {
        g.get_pixel(x, y)[0] > 127
    }))
}

/// Image size without decoding the pixels.
pub fn image_size(path: &Path) -> Result<(u32, u32)> {
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
