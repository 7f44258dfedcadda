//! Frames as bytes: in the client's pixel format, as PNG, as a FRAME message's payload,
//! or cut into UDP datagrams.

use crate::device::DeviceFrame;
use crate::protocol::{Chunk, FrameHeader, PixelFormat, CHUNK_HEADER_LEN};

/// A frame in the client's pixel format.
#[must_use]
pub fn encode_pixels(f: &DeviceFrame, format: PixelFormat) -> Vec<u8> {
    match format {
        PixelFormat::Rgb8 => f.rgb8.clone(),
        PixelFormat::Rgb565 => f
            .rgb8
            .chunks_exact(3)
            .flat_map(|p| (u16::from(p[0] >> 3) << 11 | u16::from(p[1] >> 2) << 5 | u16::from(p[2] >> 3)).to_be_bytes())
            .collect(),
        PixelFormat::Png => png(f),
    }
}

/// PNG bytes of a frame.
#[must_use]
pub fn png(f: &DeviceFrame) -> Vec<u8> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    let enc = image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    );
    // Writing into a Vec fails only on a size mismatch, which `Frame` rules out.
    if let Err(e) = enc.write_image(&f.rgb8, f.width, f.height, image::ExtendedColorType::Rgb8) {
        tracing::error!("PNG encoding failed: {e}");
    }
    out
}

/// FRAME message payload.
#[must_use]
pub fn frame_payload(f: &DeviceFrame, format: PixelFormat) -> Vec<u8> {
    let h = FrameHeader {
        number: f.number,
        width: u16::try_from(f.width).unwrap_or(u16::MAX),
        height: u16::try_from(f.height).unwrap_or(u16::MAX),
        format: format as u8,
        render_us: f.render_us,
        shapes: f.shapes,
        lights: f.lights,
    };
    let mut b = h.encode().to_vec();
    b.extend_from_slice(&encode_pixels(f, format));
    b
}

/// A frame as PNG, cut into FRAME_CHUNK datagrams of at most `chunk` payload bytes.
#[must_use]
pub fn chunk_frame(f: &DeviceFrame, chunk: usize) -> Vec<Vec<u8>> {
    let png = png(f);
    let parts: Vec<&[u8]> = png.chunks(chunk.max(1)).collect();
    let count = u16::try_from(parts.len()).unwrap_or(u16::MAX);
    parts
        .iter()
        .take(usize::from(count))
        .enumerate()
        .map(|(i, p)| {
            let c = Chunk {
                frame: f.number,
                index: u16::try_from(i).unwrap_or(u16::MAX),
                count,
                total: u32::try_from(png.len()).unwrap_or(u32::MAX),
            };
            let mut d = Vec::with_capacity(CHUNK_HEADER_LEN + p.len());
            d.extend_from_slice(&c.encode());
            d.extend_from_slice(p);
            d
        })
        .collect()
}
