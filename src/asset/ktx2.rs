//! KTX2 images with Basis Universal payloads (KHR_texture_basisu), the form
//! web pipelines (gltfpack `-tc`, glTF-Transform `etc1s`/`uastc`) leave
//! textures in: level 0 transcoded to RGBA8 by the `basisu` crate, which
//! matches Binomial's transcoder byte for byte (tests/ktx2.rs checks it
//! against the official WebAssembly build).

use anyhow::{Result, anyhow, bail};
use basisu::{DecodeFlags, TargetFormat, Transcoder};

/// The KTX2 file identifier, `«KTX 20»\r\n\x1A\n`.
const IDENTIFIER: [u8; 12] = [0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A];

/// Whether `bytes` start as a KTX2 file does.
pub fn is_ktx2(bytes: &[u8]) -> bool {
    bytes.starts_with(&IDENTIFIER)
}

/// The widest and tallest texture bake decodes (1 GiB as RGBA8).
const MAX_SIDE: u32 = 16_384;

/// The largest mip level of a KTX2 file's first image as RGBA8, the bytes as
/// stored (sRGB for a colour texture, as glTF asks).
pub fn decode(bytes: &[u8]) -> Result<image::RgbaImage> {
    check_header(bytes)?;
    // The checks above keep the transcoder within the file; a damaged file
    // that still trips it over an index is an error, not a crash.
    std::panic::catch_unwind(|| transcode(bytes))
        .unwrap_or_else(|_| bail!("the Basis Universal transcoder failed on it (a damaged file)"))
}

/// The size of the file's first image, from its checked header.
pub fn dimensions(bytes: &[u8]) -> Result<(u32, u32)> {
    check_header(bytes)?;
    let field = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    Ok((field(20), field(24)))
}

fn transcode(bytes: &[u8]) -> Result<image::RgbaImage> {
    let texture = Transcoder::new(bytes).map_err(|e| anyhow!("not a Basis Universal KTX2 file ({e:?})"))?;
    if texture.is_video() {
        bail!("a Basis Universal video, not a texture");
    }
    let (width, height) = texture.base_dimensions();
    let pixels = texture
        .transcode(0, TargetFormat::Rgba32, DecodeFlags::NONE)
        .map_err(|e| anyhow!("its {:?} payload does not decode to RGBA ({e:?})", texture.source_format()))?;
    image::RgbaImage::from_raw(width, height, pixels)
        .ok_or_else(|| anyhow!("the decoded level does not hold {width}×{height} pixels"))
}

/// What the transcoder takes on trust from the header, checked first: it
/// allocates a Zstandard level's stated size before inflating it, so a
/// damaged length aborts the process (found by tests/ktx2.rs). glTF's KTX2
/// images are single 2D images (KHR_texture_basisu), and a Basis level holds
/// at most 16 bytes per 4×4 block.
fn check_header(bytes: &[u8]) -> Result<()> {
    // The header's fields are little-endian u32s from byte 12, the level
    // index (offset, length, uncompressed length as u64s) from byte 80.
    let field = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    if bytes.len() < 104 {
        bail!("a KTX2 file of {} bytes is shorter than its header", bytes.len());
    }
    let (width, height, depth, layers, faces) = (field(20), field(24), field(28), field(32), field(36));
    if !(1..=MAX_SIDE).contains(&width) || !(1..=MAX_SIDE).contains(&height) {
        bail!("its size {width}×{height} is outside 1 to {MAX_SIDE} texels a side");
    }
    if depth != 0 || layers > 1 || faces != 1 {
        bail!("a texture of depth {depth}, {layers} layers and {faces} faces is no single 2D image");
    }
    // The data format descriptor, key/value data and supercompression
    // global data, then level 0, must lie inside the file.
    let long = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"));
    let parts = [
        ("data format descriptor", u64::from(field(48)), u64::from(field(52))),
        ("key/value data", u64::from(field(56)), u64::from(field(60))),
        ("supercompression global data", long(64), long(72)),
        ("first level", long(80), long(88)),
    ];
    for (part, offset, length) in parts {
        if offset.checked_add(length).is_none_or(|end| end > bytes.len() as u64) {
            bail!("its {part} ({length} bytes at {offset}) runs past the end of the file ({} bytes)", bytes.len());
        }
    }
    // Each key/value entry and its padding must end inside the key/value
    // data: basisu 0.1.0 reads past a last entry whose padding overruns it.
    let (mut at, end) = (field(56) as usize, field(56) as usize + field(60) as usize);
    while end - at > 4 {
        let length = field(at) as usize;
        if length < 2 || end - at - 4 < length {
            break; // the transcoder stops here too
        }
        at = (at + 4 + length).next_multiple_of(4);
        if at > end {
            bail!("its key/value data runs past its stated length ({} bytes at {})", field(60), field(56));
        }
    }
    let uncompressed = long(96);
    let most = u64::from(width.div_ceil(4)) * u64::from(height.div_ceil(4)) * 16;
    if uncompressed > most {
        bail!("its first level claims {uncompressed} bytes, more than a {width}×{height} Basis texture holds");
    }
    Ok(())
}
