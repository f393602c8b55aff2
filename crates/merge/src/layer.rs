//! Reading and decoding painted layers: the I/O edge of stage 1.

use crowd_core::config::{LayerSpec, PipelineFile};
use crowd_core::{Error, Hash, LayerKind, Result};
use image::{DynamicImage, ImageFormat};
use std::path::PathBuf;

/// A layer file's bytes, read once: hashed for staleness, decoded only when the stage runs.
#[derive(Debug, Clone)]
pub struct LayerBytes {
    pub spec: LayerSpec,
    /// The resolved path, for messages.
    pub path: PathBuf,
    pub bytes: Vec<u8>,
    pub hash: Hash,
}

/// The widest or tallest layer stage 1 decodes, in pixels.
pub const MAX_LAYER_SIDE: u32 = 16_384;
/// The largest layer in pixels in all: 8,192 x 8,192 (decoded as 4 bytes a channel, 1 GiB as
/// RGBA).
pub const MAX_LAYER_PIXELS: u64 = 8_192 * 8_192;

/// Reads every layer named in the pipeline. A missing file names the pipeline line of its path;
/// a PNG larger than [`MAX_LAYER_SIDE`] or [`MAX_LAYER_PIXELS`] is refused from its header,
/// before anything is decoded, and so is an `export.gltf_region` off the first layer's map.
pub fn read_layers(pipeline: &PipelineFile) -> Result<Vec<LayerBytes>> {
    let layers = read_files(pipeline)?;
    let mut map = None;
    for layer in &layers {
        let Some((w, h)) = header_size(&layer.bytes) else {
            continue; // not a PNG: `decode` says what is wrong with it
        };
        if w > MAX_LAYER_SIDE
            || h > MAX_LAYER_SIDE
            || u64::from(w) * u64::from(h) > MAX_LAYER_PIXELS
        {
            return Err(Error::Image {
                path: layer.path.clone(),
                message: format!(
                    "is {w} x {h} pixels (read from its header; nothing was decoded); a layer \
                     may have at most {MAX_LAYER_SIDE} pixels a side and {MAX_LAYER_PIXELS} in \
                     all: paint at a coarser scale and raise `scene.meters_per_pixel`"
                ),
            });
        }
        map.get_or_insert((w, h));
    }
    if let Some((w, h)) = map {
        let mpp = pipeline.pipeline.scene.meters_per_pixel;
        pipeline.check_region((f64::from(w) * mpp, f64::from(h) * mpp))?;
    }
    Ok(layers)
}

/// A PNG's width and height from its header (`IHDR`, the chunk the format puts first), if it
/// has one.
fn header_size(bytes: &[u8]) -> Option<(u32, u32)> {
    let ihdr = bytes.strip_prefix(PNG_SIGNATURE)?.get(4..16)?;
    let (kind, size) = ihdr.split_at(4);
    let word = |b: &[u8]| u32::from_be_bytes(b.try_into().expect("4 bytes"));
    (kind == b"IHDR").then(|| (word(&size[..4]), word(&size[4..])))
}

/// Reads every layer's file.
fn read_files(pipeline: &PipelineFile) -> Result<Vec<LayerBytes>> {
    pipeline
        .pipeline
        .scene
        .layers
        .iter()
        .enumerate()
        .map(|(i, spec)| {
            let path = pipeline.resolve(&spec.path);
            let bytes = std::fs::read(&path).map_err(|e| {
                pipeline.field_error(
                    &format!("scene.layers[{i}].path"),
                    format!(
                        "names the {} layer `{}`, which cannot be read ({}): {e}",
                        spec.kind.name(),
                        spec.path.display(),
                        path.display()
                    ),
                )
            })?;
            let hash = Hash::of(&bytes);
            Ok(LayerBytes {
                spec: spec.clone(),
                path,
                bytes,
                hash,
            })
        })
        .collect()
}

/// Channels of a decoded layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channels {
    Gray,
    GrayAlpha,
    Rgb,
    Rgba,
}

/// A decoded image: raw channel values (0..=max) as f32, row 0 at the top (north).
#[derive(Debug, Clone)]
pub struct Raster {
    pub width: u32,
    pub height: u32,
    pub channels: Channels,
    /// 255 for 8-bit images, 65535 for 16-bit ones.
    pub max: f32,
    pub values: Vec<f32>,
}

impl Raster {
    fn count(&self) -> usize {
        match self.channels {
            Channels::Gray => 1,
            Channels::GrayAlpha => 2,
            Channels::Rgb => 3,
            Channels::Rgba => 4,
        }
    }

    /// Gray level (0..1) and alpha (0..1) of pixel `i` (row-major index). Colour pixels give
    /// their luminance (Rec. 709), for artists who saved a gray layer as RGB.
    pub fn gray_alpha(&self, i: usize) -> (f32, f32) {
        let n = self.count();
        let px = &self.values[i * n..(i + 1) * n];
        let m = self.max;
        match self.channels {
            Channels::Gray => (px[0] / m, 1.0),
            Channels::GrayAlpha => (px[0] / m, px[1] / m),
            Channels::Rgb => (luma(px) / m, 1.0),
            Channels::Rgba => (luma(px) / m, px[3] / m),
        }
    }

    /// Raw red, green and alpha (0..1) of pixel `i`, for flow maps.
    pub fn red_green_alpha(&self, i: usize) -> (f32, f32, f32) {
        let n = self.count();
        let px = &self.values[i * n..(i + 1) * n];
        let alpha = if n == 4 { px[3] / self.max } else { 1.0 };
        (px[0], px[1], alpha)
    }

    /// `"gray 8-bit"`, `"rgba 16-bit"`, ...
    pub fn format(&self) -> String {
        let channels = match self.channels {
            Channels::Gray => "gray",
            Channels::GrayAlpha => "gray+alpha",
            Channels::Rgb => "rgb",
            Channels::Rgba => "rgba",
        };
        let bits = if self.max > 255.0 { 16 } else { 8 };
        format!("{channels} {bits}-bit")
    }
}

fn luma(px: &[f32]) -> f32 {
    0.2126 * px[0] + 0.7152 * px[1] + 0.0722 * px[2]
}

/// A decoded layer, ready to merge.
#[derive(Debug, Clone)]
pub struct PaintedLayer {
    pub kind: LayerKind,
    pub weight: f64,
    pub raster: Raster,
}

const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";

/// Decodes every layer and checks that they all have the pixel size of the first one.
pub fn decode(layers: &[LayerBytes]) -> Result<Vec<PaintedLayer>> {
    let mut out: Vec<PaintedLayer> = Vec::with_capacity(layers.len());
    for layer in layers {
        let raster = decode_png(layer)?;
        if let (Some(first), Some(first_bytes)) = (out.first(), layers.first()) {
            let (w, h) = (first.raster.width, first.raster.height);
            if (raster.width, raster.height) != (w, h) {
                return Err(Error::Image {
                    path: layer.path.clone(),
                    message: format!(
                        "is {} x {} pixels but the first layer `{}` is {w} x {h} pixels; \
                         every layer of a scene must have the same pixel size",
                        raster.width,
                        raster.height,
                        first_bytes.path.display()
                    ),
                });
            }
        }
        if layer.spec.kind == LayerKind::Flow
            && matches!(raster.channels, Channels::Gray | Channels::GrayAlpha)
        {
            return Err(Error::Image {
                path: layer.path.clone(),
                message: format!(
                    "is a {} image; a `Flow` layer must be RGB or RGBA (R = east, G = north, \
                     128 = zero, A = weight). Gray direction layers are of kind `Direction`",
                    raster.format()
                ),
            });
        }
        out.push(PaintedLayer {
            kind: layer.spec.kind,
            weight: layer.spec.weight,
            raster,
        });
    }
    Ok(out)
}

pub(crate) fn decode_png(layer: &LayerBytes) -> Result<Raster> {
    let bad = |message: String| Error::Image {
        path: layer.path.clone(),
        message,
    };
    if !layer.bytes.starts_with(PNG_SIGNATURE) {
        let head: String = layer
            .bytes
            .iter()
            .take(8)
            .map(|b| format!("{b:02x}"))
            .collect();
        return Err(bad(format!(
            "is not a PNG image: expected the PNG signature 89504e470d0a1a0a at byte 0, found \
             `{head}` ({} bytes in all)",
            layer.bytes.len()
        )));
    }
    let image =
        image::load_from_memory_with_format(&layer.bytes, ImageFormat::Png).map_err(|e| {
            bad(format!(
                "is a damaged or truncated PNG ({} bytes): {e}",
                layer.bytes.len()
            ))
        })?;
    let (width, height) = (image.width(), image.height());
    let f = |v: Vec<u8>| v.into_iter().map(f32::from).collect::<Vec<f32>>();
    let g = |v: Vec<u16>| v.into_iter().map(f32::from).collect::<Vec<f32>>();
    let (channels, max, values) = match image {
        DynamicImage::ImageLuma8(i) => (Channels::Gray, 255.0, f(i.into_raw())),
        DynamicImage::ImageLumaA8(i) => (Channels::GrayAlpha, 255.0, f(i.into_raw())),
        DynamicImage::ImageRgb8(i) => (Channels::Rgb, 255.0, f(i.into_raw())),
        DynamicImage::ImageRgba8(i) => (Channels::Rgba, 255.0, f(i.into_raw())),
        DynamicImage::ImageLuma16(i) => (Channels::Gray, 65535.0, g(i.into_raw())),
        DynamicImage::ImageLumaA16(i) => (Channels::GrayAlpha, 65535.0, g(i.into_raw())),
        DynamicImage::ImageRgb16(i) => (Channels::Rgb, 65535.0, g(i.into_raw())),
        DynamicImage::ImageRgba16(i) => (Channels::Rgba, 65535.0, g(i.into_raw())),
        other => {
            return Err(bad(format!(
                "has the pixel format {:?}; expected 8- or 16-bit gray, gray+alpha, RGB or RGBA",
                other.color()
            )));
        }
    };
    Ok(Raster {
        width,
        height,
        channels,
        max,
        values,
    })
}
