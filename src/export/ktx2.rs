//! The KTX2 lightmap `NAME.lightmap0.ktx2`: the EXR's L_lm per texel as an
//! engine takes a float lightmap (README, "Using the lightmap in an engine").
//! Bevy's `Lightmap` reads it as it is: `VK_FORMAT_E5B9G9R9_UFLOAT_PACK32`
//! (wgpu's filterable `Rgb9e5Ufloat`), one mip level, Zstandard
//! supercompression, linear RGB with Rec. 709 primaries, no π.
//!
//! Rows run as in the EXR and the PNGs: the first row is the top of the
//! image, at glTF's UV (0, 0) (KTX2's default orientation, `KTXorientation`
//! "rd", written out all the same). The container and its data format
//! descriptor come from the `ktx2` crate, the level's Zstandard frame from
//! `ruzstd`; only the shared-exponent packing is here, by the rules Vulkan
//! and OpenGL (EXT_texture_shared_exponent) share: each channel clamped to
//! [0, 65408] (NaN to 0), one exponent from the largest, every mantissa
//! rounded to nearest. A channel is then within half a mantissa step of its
//! value, at most 2^-9 of the texel's largest channel.

use ::ktx2::{Format, Header, Index, LevelIndex, SupercompressionScheme, dfd};
use anyhow::{Result, anyhow, ensure};

/// Mantissa bits per channel.
const MANTISSA_BITS: i32 = 9;
/// The exponent's bias.
const BIAS: i32 = 15;
/// The largest value E5B9G9R9 holds: (2^9 − 1)/2^9 · 2^(31 − 15).
pub const E5B9G9R9_MAX: f32 = 65408.0;

/// `rgb` as one E5B9G9R9 texel: red in bits 0–8, green 9–17, blue 18–26,
/// the shared exponent in 27–31.
pub fn pack_e5b9g9r9(rgb: [f32; 3]) -> u32 {
    let channels = rgb.map(|v| if v.is_nan() { 0.0 } else { f64::from(v.clamp(0.0, E5B9G9R9_MAX)) });
    let largest = channels[0].max(channels[1]).max(channels[2]);
    // floor(log2(largest)), exact: every f32 is a normal f64.
    let floor_log2 = if largest > 0.0 { ((largest.to_bits() >> 52) & 0x7ff) as i32 - 1023 } else { -BIAS - 1 };
    let mut exponent = floor_log2.max(-BIAS - 1) + 1 + BIAS;
    let step = |exponent: i32| 2f64.powi(exponent - BIAS - MANTISSA_BITS);
    if (largest / step(exponent) + 0.5).floor() >= f64::from(1 << MANTISSA_BITS) {
        exponent += 1; // the largest rounded up to 2^9: one exponent more
    }
    let [r, g, b] = channels.map(|v| (v / step(exponent) + 0.5).floor() as u32);
    (exponent as u32) << 27 | b << 18 | g << 9 | r
}

/// The RGB value of an E5B9G9R9 texel: mantissa · 2^(exponent − 15 − 9).
pub fn unpack_e5b9g9r9(texel: u32) -> [f32; 3] {
    let scale = 2f32.powi((texel >> 27) as i32 - BIAS - MANTISSA_BITS);
    [0, 9, 18].map(|shift| ((texel >> shift) & 0x1ff) as f32 * scale)
}

/// The KTX2 file of a `width` × `height` image of `pixels` (row-major, the
/// first row the top): E5B9G9R9, one level, Zstandard-supercompressed.
pub fn encode(width: u32, height: u32, pixels: &[[f32; 3]]) -> Result<Vec<u8>> {
    encode_with_depth(width, height, 0, pixels)
}

/// As [`encode`], a 3D texture of `depth` slices of `width` × `height`,
/// one after another (a light probe volume).
pub fn encode_volume(width: u32, height: u32, depth: u32, pixels: &[[f32; 3]]) -> Result<Vec<u8>> {
    ensure!(depth > 0, "a volume without slices");
    encode_with_depth(width, height, depth, pixels)
}

/// A 2D image (`depth` 0) or a volume.
fn encode_with_depth(width: u32, height: u32, depth: u32, pixels: &[[f32; 3]]) -> Result<Vec<u8>> {
    ensure!(width > 0 && height > 0, "an empty image ({width}×{height})");
    ensure!(
        pixels.len() as u64 == u64::from(width) * u64::from(height) * u64::from(depth.max(1)),
        "{} texels for {width}×{height}×{}",
        pixels.len(),
        depth.max(1)
    );
    let texels: Vec<u8> = pixels.iter().flat_map(|&p| pack_e5b9g9r9(p).to_le_bytes()).collect();
    let level = ruzstd::encoding::compress_to_vec(texels.as_slice(), ruzstd::encoding::CompressionLevel::Fastest);
    let format = Format::E5B9G9R9_UFLOAT_PACK32;
    let (basic, type_size) =
        dfd::Basic::from_format(format).map_err(|e| anyhow!("no KTX2 data format descriptor for {format:?}: {e:?}"))?;
    let block = dfd::Block::Basic(basic).to_vec();
    // The DFD section: its total length, then its one block.
    let dfd_section = [&(4 + block.len() as u32).to_le_bytes()[..], &block].concat();
    let writer = format!("bake {}", env!("CARGO_PKG_VERSION"));
    // Right, down, and for a volume into the screen: KTX2's defaults, said.
    let orientation = if depth > 0 { "rdi" } else { "rd" };
    let kvd = key_value_data(&[("KTXorientation", orientation), ("KTXwriter", &writer)]);
    let dfd_offset = Header::LENGTH + LevelIndex::LENGTH;
    let kvd_offset = dfd_offset + dfd_section.len();
    // Every section above is a whole number of 4-byte words: so is the level's offset.
    let level_offset = kvd_offset + kvd.len();
    let header = Header {
        format: Some(format),
        type_size,
        pixel_width: width,
        pixel_height: height,
        pixel_depth: depth,
        layer_count: 0,
        face_count: 1,
        level_count: 1,
        supercompression_scheme: Some(SupercompressionScheme::Zstandard),
        index: Index {
            dfd_byte_offset: dfd_offset as u32,
            dfd_byte_length: dfd_section.len() as u32,
            kvd_byte_offset: kvd_offset as u32,
            kvd_byte_length: kvd.len() as u32,
            sgd_byte_offset: 0,
            sgd_byte_length: 0,
        },
    };
    let index = LevelIndex {
        byte_offset: level_offset as u64,
        byte_length: level.len() as u64,
        uncompressed_byte_length: texels.len() as u64,
    };
    Ok([&header.as_bytes()[..], &index.as_bytes(), &dfd_section, &kvd, &level].concat())
}

/// KTX2 key/value data: for each entry, sorted by key, its length, the key,
/// a NUL, the value and a NUL (string values), padded to 4 bytes.
fn key_value_data(entries: &[(&str, &str)]) -> Vec<u8> {
    let mut bytes = Vec::new();
    for (key, value) in entries {
        let entry = [key.as_bytes(), b"\0", value.as_bytes(), b"\0"].concat();
        bytes.extend_from_slice(&(entry.len() as u32).to_le_bytes());
        bytes.extend_from_slice(&entry);
        bytes.resize(bytes.len().next_multiple_of(4), 0);
    }
    bytes
}

/// The E5B9G9R9 texels of a KTX2 file as [`encode`] writes it, row by row
/// from the top, with its width and height; for any other kind of file an
/// error that says what differs. Decompresses at most `max_texels` texels.
pub fn decode(bytes: &[u8], max_texels: u64) -> Result<(u32, u32, Vec<u32>)> {
    use std::io::Read;
    let reader = ::ktx2::Reader::new(bytes).map_err(|e| anyhow!("not a KTX2 file ({e:?})"))?;
    let header = reader.header();
    ensure!(header.format == Some(Format::E5B9G9R9_UFLOAT_PACK32), "its format is {:?}, not E5B9G9R9", header.format);
    ensure!(
        header.supercompression_scheme == Some(SupercompressionScheme::Zstandard),
        "its level is not Zstandard-supercompressed"
    );
    ensure!(
        (header.pixel_depth, header.layer_count, header.face_count, header.level_count) == (0, 0, 1, 1),
        "it is not one level of one 2D image"
    );
    let texels = u64::from(header.pixel_width) * u64::from(header.pixel_height);
    ensure!(texels <= max_texels, "it declares {texels} texels, more than the {max_texels} expected");
    let level = reader.levels().next().ok_or_else(|| anyhow!("it has no level"))?;
    let decoder = ruzstd::decoding::StreamingDecoder::new(level.data)
        .map_err(|e| anyhow!("its level is not a Zstandard frame ({e})"))?;
    let mut data = Vec::new();
    decoder.take(texels * 4 + 1).read_to_end(&mut data).map_err(|e| anyhow!("its level does not decompress ({e})"))?;
    ensure!(
        data.len() as u64 == texels * 4,
        "its level holds {} bytes, not the {} of its texels",
        data.len(),
        texels * 4
    );
    let texels = data.chunks_exact(4).map(|t| u32::from_le_bytes([t[0], t[1], t[2], t[3]])).collect();
    Ok((header.pixel_width, header.pixel_height, texels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values_pack_to_the_specified_bits() {
        // 1.0: exponent 16, mantissas 256.
        assert_eq!(pack_e5b9g9r9([1.0; 3]), 16 << 27 | 256 << 18 | 256 << 9 | 256);
        assert_eq!(pack_e5b9g9r9([0.5; 3]), 15 << 27 | 256 << 18 | 256 << 9 | 256);
        // Red in the low bits, blue in the high ones, under the largest's exponent.
        assert_eq!(pack_e5b9g9r9([1.0, 0.5, 0.25]), 16 << 27 | 64 << 18 | 128 << 9 | 256);
        // The largest value is every bit set; anything above clamps to it.
        assert_eq!(pack_e5b9g9r9([E5B9G9R9_MAX; 3]), u32::MAX);
        assert_eq!(pack_e5b9g9r9([1e6, f32::INFINITY, 65408.0]), u32::MAX);
        assert_eq!(pack_e5b9g9r9([0.0; 3]), 0);
        // Negatives and NaN never occur in a lightmap; they pack as 0.
        assert_eq!(pack_e5b9g9r9([-1.0, f32::NAN, -0.0]), 0);
        // The smallest step, 2^-24 at exponent 0; half of it rounds up, a quarter down.
        assert_eq!(pack_e5b9g9r9([2f32.powi(-24), 0.0, 0.0]), 1);
        assert_eq!(pack_e5b9g9r9([0.0, 2f32.powi(-25), 0.0]), 1 << 9);
        assert_eq!(pack_e5b9g9r9([0.0, 0.0, 2f32.powi(-26)]), 0);
        // A largest channel that rounds up to 512 takes the next exponent.
        assert_eq!(pack_e5b9g9r9([0.9995, 0.0, 0.0]), pack_e5b9g9r9([1.0, 0.0, 0.0]));
        assert_eq!(unpack_e5b9g9r9(16 << 27 | 64 << 18 | 128 << 9 | 256), [1.0, 0.5, 0.25]);
        assert_eq!(unpack_e5b9g9r9(u32::MAX), [E5B9G9R9_MAX; 3]);
        assert_eq!(unpack_e5b9g9r9(1), [2f32.powi(-24), 0.0, 0.0]);
    }

    #[test]
    fn every_channel_is_within_half_a_step_of_its_value() {
        // A spread of magnitudes and ratios between channels, over the whole range.
        let mut worst = 0.0f64;
        for i in 0..20_000u32 {
            let t = f64::from(i) / 20_000.0;
            let rgb = [
                (2f64.powf(-30.0 + 47.0 * t)) as f32,
                (2f64.powf(-30.0 + 47.0 * ((t * 7.3) % 1.0))) as f32,
                (2f64.powf(-30.0 + 47.0 * ((t * 13.7) % 1.0))) as f32,
            ];
            let decoded = unpack_e5b9g9r9(pack_e5b9g9r9(rgb));
            let largest = f64::from(rgb.iter().copied().fold(0.0f32, f32::max).min(E5B9G9R9_MAX));
            for c in 0..3 {
                let error = (f64::from(decoded[c]) - f64::from(rgb[c].min(E5B9G9R9_MAX))).abs();
                // Half a step: 2^-9 of the largest (a hair more where it rounds up), or of the smallest exponent's.
                assert!(error <= largest * 2f64.powi(-9) * (1.0 + 2f64.powi(-9)) + 2f64.powi(-25), "{rgb:?}");
                if largest > 1e-4 {
                    worst = worst.max(error / largest);
                }
            }
        }
        assert!(worst > 2f64.powi(-10), "the test spans real rounding ({worst})");
    }

    #[test]
    fn the_file_reads_back_with_its_header_descriptor_and_keys() {
        let pixels: Vec<[f32; 3]> = (0..12).map(|i| [i as f32, 0.5, 100.0 / (i + 1) as f32]).collect();
        let bytes = encode(4, 3, &pixels).unwrap();
        let reader = ::ktx2::Reader::new(&bytes[..]).unwrap();
        let header = reader.header();
        assert_eq!(header.format, Some(Format::E5B9G9R9_UFLOAT_PACK32));
        assert_eq!((header.type_size, header.pixel_width, header.pixel_height), (4, 4, 3));
        assert_eq!((header.pixel_depth, header.layer_count, header.face_count, header.level_count), (0, 0, 1, 1));
        assert_eq!(header.supercompression_scheme, Some(SupercompressionScheme::Zstandard));
        assert_eq!(reader.transfer_function(), Some(::ktx2::TransferFunction::Linear));
        let keys: Vec<(&str, &[u8])> = reader.key_value_data().collect();
        assert_eq!(keys[0], ("KTXorientation", &b"rd\0"[..]));
        assert_eq!(reader.writer(), Some(format!("bake {}\0", env!("CARGO_PKG_VERSION")).as_str()));
        let level = reader.levels().next().unwrap();
        assert_eq!(level.uncompressed_byte_length, 48);
        assert_eq!(level.data.as_ptr() as usize % 4, bytes.as_ptr() as usize % 4, "4-byte aligned");
        let mut texels = Vec::new();
        std::io::Read::read_to_end(&mut ruzstd::decoding::StreamingDecoder::new(level.data).unwrap(), &mut texels)
            .unwrap();
        let expected: Vec<u8> = pixels.iter().flat_map(|&p| pack_e5b9g9r9(p).to_le_bytes()).collect();
        assert_eq!(texels, expected);
        assert!(encode(4, 2, &pixels).is_err());
    }
}
