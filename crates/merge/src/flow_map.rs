//! A flow edit's painted map (`EditKind::FlowMap`), decoded as the layers are and read as
//! velocities: R = east, G = north, 128 = zero, A = weight, a full-strength pixel at the edit's
//! speed. Stage 7 reads it; its PNG checks are the layers'.

use crate::layer::{Channels, LayerBytes, decode_png};
use crowd_core::config::LayerSpec;
use crowd_core::flow_map::VelocityMap;
use crowd_core::{Error, Hash, LayerKind, Result};
use glam::DVec2;
use std::path::PathBuf;

/// The flow map in `bytes` (read from `path`) as velocities of at most `speed_m_s`, over maps
/// of `size` pixels of `meters_per_pixel` (the layers'); `edit` names the edit for errors.
pub fn decode_flow_map(
    path: PathBuf,
    bytes: Vec<u8>,
    speed_m_s: f64,
    meters_per_pixel: f64,
    size: (u32, u32),
    edit: &str,
) -> Result<VelocityMap> {
    let layer = LayerBytes {
        spec: LayerSpec {
            kind: LayerKind::Flow,
            path: path.clone(),
            weight: 1.0,
        },
        hash: Hash::of(&bytes),
        path: path.clone(),
        bytes,
    };
    let bad = |message: String| Error::Image {
        path: path.clone(),
        message: format!("(the flow map of edit `{edit}`) {message}"),
    };
    // The layers' own checks: a PNG, whole, of a format we read.
    let raster = decode_png(&layer).map_err(|e| match e {
        Error::Image { message, .. } => bad(message),
        other => other,
    })?;
    if (raster.width, raster.height) != size {
        return Err(bad(format!(
            "is {} x {} pixels; expected {} x {}, the size of the scene's layers, so that its \
             pixels lie on theirs",
            raster.width, raster.height, size.0, size.1
        )));
    }
    if matches!(raster.channels, Channels::Gray | Channels::GrayAlpha) {
        return Err(bad(format!(
            "is a {} image; expected RGB or RGBA (R = east, G = north, 128 = zero, A = weight)",
            raster.format()
        )));
    }
    let zero = (raster.max + 1.0) / 2.0;
    let range = raster.max - zero;
    // Shorter than this is "no direction" (8-bit rounding round 128), as stage 1 reads flow.
    let dead_zone = 1.5 / 127.0;
    let n = (raster.width * raster.height) as usize;
    let (mut velocity, mut weight) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let (red, green, alpha) = raster.red_green_alpha(i);
        let v = DVec2::new(f64::from(red - zero), f64::from(green - zero)) / f64::from(range);
        let v = if v.length() > dead_zone {
            v.clamp_length_max(1.0)
        } else {
            DVec2::ZERO
        };
        velocity.push(v * speed_m_s);
        weight.push(f64::from(alpha));
    }
    Ok(VelocityMap {
        width: raster.width,
        height: raster.height,
        meters_per_pixel,
        velocity,
        weight,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{GrayImage, Rgba, RgbaImage};

    fn png(image: impl Into<image::DynamicImage>) -> Vec<u8> {
        let mut bytes = Vec::new();
        image
            .into()
            .write_to(
                &mut std::io::Cursor::new(&mut bytes),
                image::ImageFormat::Png,
            )
            .unwrap();
        bytes
    }

    fn decode(bytes: Vec<u8>, size: (u32, u32)) -> Result<VelocityMap> {
        decode_flow_map("drift.png".into(), bytes, 1.5, 0.5, size, "drift")
    }

    #[test]
    fn red_is_east_green_is_north_and_alpha_is_the_weight() {
        let mut image = RgbaImage::from_pixel(2, 2, Rgba([128, 128, 128, 0]));
        image.put_pixel(0, 0, Rgba([255, 128, 0, 255])); // north-west: east
        image.put_pixel(1, 1, Rgba([128, 1, 0, 102])); // south-east: south, 40 %
        image.put_pixel(1, 0, Rgba([129, 128, 0, 255])); // within 8-bit rounding of zero
        let map = decode(png(image), (2, 2)).unwrap();
        assert_eq!(map.velocity[0], DVec2::new(1.5, 0.0));
        assert_eq!(map.velocity[3], DVec2::new(0.0, -1.5));
        assert_eq!(map.velocity[1], DVec2::ZERO);
        assert_eq!(map.weight[0], 1.0);
        assert!((map.weight[3] - 0.4).abs() < 1e-6);
        // The south-east pixel is at x 0.5-1 m, y 0-0.5 m (0.5 m pixels).
        let (v, w) = map
            .mean_over(DVec2::new(0.5, 0.0), DVec2::new(1.0, 0.5))
            .unwrap();
        assert_eq!(v, DVec2::new(0.0, -1.5));
        assert!((w - 0.4).abs() < 1e-6);
    }

    #[test]
    fn a_gray_map_a_map_of_another_size_and_a_broken_file_are_refused_naming_the_edit() {
        let rgba = png(RgbaImage::new(2, 2));
        let err = decode(rgba, (4, 4)).unwrap_err().to_string();
        assert!(
            err.contains("drift.png") && err.contains("edit `drift`"),
            "{err}"
        );
        assert!(err.contains("2 x 2") && err.contains("4 x 4"), "{err}");
        let err = decode(png(GrayImage::new(2, 2)), (2, 2))
            .unwrap_err()
            .to_string();
        assert!(err.contains("expected RGB or RGBA"), "{err}");
        let mut cut = png(RgbaImage::new(2, 2));
        cut.truncate(cut.len() / 2);
        let err = decode(cut, (2, 2)).unwrap_err().to_string();
        assert!(err.contains("damaged or truncated"), "{err}");
    }
}
