//! A glTF image's bytes decoded to RGBA8: PNG with the `png` crate (palette, low-bit grey and
//! `tRNS` expanded, 16-bit channels cut to their high byte), JPEG with `zune-jpeg` (output as
//! RGBA); the two formats glTF 2.0's core allows (`image/png`, `image/jpeg`), told apart by their
//! signatures rather than by a MIME type or file extension, which exporters get wrong.

/// An image decoded to 8-bit RGBA.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub rgba8: Vec<u8>,
}

const PNG: &[u8] = b"\x89PNG\r\n\x1a\n";
const JPEG: &[u8] = b"\xff\xd8\xff";
/// Bytes with neither signature.
const NEITHER: &str =
    "does not decode: neither PNG nor JPEG (the formats glTF 2.0 allows); convert it to PNG";

/// `bytes` decoded, or why not (one line saying what to do).
pub(super) fn decode(bytes: &[u8]) -> Result<Texture, String> {
    if bytes.starts_with(PNG) {
        png(bytes)
            .map_err(|e| format!("does not decode: its PNG: {e}; export it again as PNG or JPEG"))
    } else if bytes.starts_with(JPEG) {
        jpeg(bytes).map_err(|e| format!("does not decode: its JPEG: {e}; export it again as PNG"))
    } else {
        Err(NEITHER.into())
    }
}

/// `bytes`' width and height from the PNG or JPEG header alone, or why not (as [`decode`]).
pub(super) fn size(bytes: &[u8]) -> Result<(u32, u32), String> {
    if bytes.starts_with(PNG) {
        let r = png::Decoder::new(std::io::Cursor::new(bytes)).read_info();
        let r = r.map_err(|e| {
            format!("does not decode: its PNG: {e}; export it again as PNG or JPEG")
        })?;
        Ok((r.info().width, r.info().height))
    } else if bytes.starts_with(JPEG) {
        let mut d = jpeg_decoder(bytes);
        d.decode_headers()
            .map_err(|e| format!("does not decode: its JPEG: {e}; export it again as PNG"))?;
        Ok(d.info().map_or((0, 0), |i| (u32::from(i.width), u32::from(i.height))))
    } else {
        Err(NEITHER.into())
    }
}

fn png(bytes: &[u8]) -> Result<Texture, png::DecodingError> {
    let mut d = png::Decoder::new(std::io::Cursor::new(bytes));
    d.set_transformations(png::Transformations::normalize_to_color8());
    let mut r = d.read_info()?;
    let size = r.output_buffer_size().ok_or(png::DecodingError::LimitsExceeded)?;
    let mut buf = vec![0; size];
    let info = r.next_frame(&mut buf)?;
    buf.truncate(info.buffer_size());
    let channels = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        // EXPAND turns indexed colour into RGB or RGBA.
        png::ColorType::Rgba | png::ColorType::Indexed => 4,
    };
    Ok(Texture { width: info.width, height: info.height, rgba8: to_rgba8(&buf, channels) })
}

fn jpeg(bytes: &[u8]) -> Result<Texture, zune_jpeg::errors::DecodeErrors> {
    let mut d = jpeg_decoder(bytes);
    let rgba8 = d.decode()?;
    let (w, h) = d.info().map_or((0, 0), |i| (u32::from(i.width), u32::from(i.height)));
    Ok(Texture { width: w, height: h, rgba8 })
}

/// A JPEG decoder to RGBA over `bytes`, its size limits JPEG's own (65,535 a side; zune's default
/// of 16,384 would make a valid image bad input where the device allows more).
fn jpeg_decoder(
    bytes: &[u8],
) -> zune_jpeg::JpegDecoder<zune_jpeg::zune_core::bytestream::ZCursor<&[u8]>> {
    use zune_jpeg::zune_core::{bytestream::ZCursor, colorspace::ColorSpace, options};
    let max = usize::from(u16::MAX);
    let o = options::DecoderOptions::default()
        .jpeg_set_out_colorspace(ColorSpace::RGBA)
        .set_max_width(max)
        .set_max_height(max);
    zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), o)
}

/// 8-bit texels of `channels` (grey, grey + alpha, RGB, RGBA) as RGBA.
fn to_rgba8(px: &[u8], channels: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(px.len() / channels * 4);
    for c in px.chunks_exact(channels) {
        out.extend(match channels {
            1 => [c[0], c[0], c[0], 255],
            2 => [c[0], c[0], c[0], c[1]],
            3 => [c[0], c[1], c[2], 255],
            _ => [c[0], c[1], c[2], c[3]],
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::decode;

    fn png(color: png::ColorType, depth: png::BitDepth, w: u32, data: &[u8]) -> Vec<u8> {
        let mut bytes = Vec::new();
        let mut e = png::Encoder::new(&mut bytes, w, 1);
        e.set_color(color);
        e.set_depth(depth);
        e.write_header().unwrap().write_image_data(data).unwrap();
        bytes
    }

    #[test]
    fn png_colour_types_become_rgba8() {
        use png::{BitDepth as B, ColorType as C};
        let t = decode(&png(C::Rgba, B::Eight, 1, &[1, 2, 3, 4])).unwrap();
        assert_eq!((t.width, t.height, t.rgba8), (1, 1, vec![1, 2, 3, 4]));
        assert_eq!(decode(&png(C::Rgb, B::Eight, 1, &[9, 8, 7])).unwrap().rgba8, [9, 8, 7, 255]);
        assert_eq!(
            decode(&png(C::Grayscale, B::Eight, 2, &[5, 6])).unwrap().rgba8,
            [5, 5, 5, 255, 6, 6, 6, 255]
        );
        assert_eq!(
            decode(&png(C::GrayscaleAlpha, B::Eight, 1, &[5, 9])).unwrap().rgba8,
            [5, 5, 5, 9]
        );
        // 16-bit: the high byte (big-endian in the file).
        assert_eq!(
            decode(&png(C::Rgb, B::Sixteen, 1, &[1, 0xff, 2, 0, 3, 0x80])).unwrap().rgba8,
            [1, 2, 3, 255]
        );
    }

    #[test]
    fn the_header_alone_gives_the_size() {
        use png::{BitDepth as B, ColorType as C};
        // A header that claims 40000 x 40000: its size without allocating its texels.
        let mut big = png(C::Rgba, B::Eight, 1, &[1, 2, 3, 4]);
        big[16..20].copy_from_slice(&40000u32.to_be_bytes());
        big[20..24].copy_from_slice(&40000u32.to_be_bytes());
        let crc = crc32(&big[12..29]);
        big[29..33].copy_from_slice(&crc.to_be_bytes());
        assert_eq!(super::size(&big).unwrap(), (40000, 40000));
        assert_eq!(super::size(&png(C::Rgb, B::Eight, 3, &[0; 9])).unwrap(), (3, 1));
        assert!(super::size(b"GIF89a").unwrap_err().contains("convert it to PNG"));
    }

    /// PNG's chunk CRC (ISO 3309), for the edited header above.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }

    #[test]
    fn garbage_and_other_formats_say_what_to_do() {
        assert!(decode(b"GIF89a....").unwrap_err().contains("convert it to PNG"));
        let mut cut = png(png::ColorType::Rgb, png::BitDepth::Eight, 1, &[1, 2, 3]);
        cut.truncate(cut.len() - 20);
        assert!(decode(&cut).unwrap_err().contains("does not decode: its PNG"));
        assert!(decode(b"\xff\xd8\xff\xe0garbage")
            .unwrap_err()
            .contains("does not decode: its JPEG"));
    }
}
