//! Reading environment maps (OpenEXR through the `exr` crate, Radiance RGBE through the
//! `image` crate) and sanitising them (non-finite and negative texels).
//!
//! The format is chosen by the file's first bytes, not its name: OpenEXR files start with
//! `76 2f 31 01`, Radiance files with `#?`. Every error is a single line that starts with
//! `environment '<path>': `.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use exr::prelude::{FlatSamples, ReadChannels, ReadLayers};

use super::{EnvLoadOptions, EnvironmentMap, LoadedEnvironment};

/// The error [`EnvironmentMap::load`] returns (inside an `anyhow::Error`): a single line
/// `environment '<path>': <problem>`, both with `{}` and `{:#}`.
#[derive(Debug, thiserror::Error)]
#[error("environment '{}': {message}", path.display())]
pub struct EnvLoadError {
    /// The file as given.
    pub path: PathBuf,
    /// What is wrong, one line.
    pub message: String,
}

const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// How many non-finite positions an error lists.
const LIST_FIRST: usize = 5;

impl EnvironmentMap {
    /// Reads an equirectangular environment map from an OpenEXR or Radiance `.hdr` file
    /// (chosen by content) and sanitises it.
    ///
    /// * EXR: scanline or tiled, any compression the `exr` crate decodes (ZIP, PIZ, RLE, PXR24,
    ///   B44, DWAA/DWAB, …), half / float / uint channels, multi-part and multi-layer files (the
    ///   first layer with R, G, B channels is used, with a notice naming it; channel names may
    ///   carry a layer prefix like `diffuse.R`), RGBA (alpha ignored), single-channel files
    ///   (`Y` or any one channel, read as grey). Mip/rip-mapped files: the full resolution.
    /// * Radiance RGBE (`#?RADIANCE` or any `#?` signature, standard `-Y H +X W` orientation);
    ///   an `EXPOSURE` / `COLORCORR` header is divided out to give the original radiance.
    /// * The map must be 2:1 (`W == 2H`) or 1×1 (a constant map).
    /// * Non-finite values are an error unless [`EnvLoadOptions::clamp_nonfinite`]; negative
    ///   channel values (lossy codecs leave small ones) are clamped to 0 with a notice giving
    ///   their count and the energy removed relative to the map's integral.
    ///
    /// Errors are [`EnvLoadError`]s: one line naming the file and the problem.
    pub fn load(path: impl AsRef<Path>, options: &EnvLoadOptions) -> anyhow::Result<LoadedEnvironment> {
        let path = path.as_ref();
        load_inner(path, options).map_err(|message| {
            anyhow::Error::new(EnvLoadError { path: path.to_path_buf(), message: one_line(&message) })
        })
    }
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

fn load_inner(path: &Path, options: &EnvLoadOptions) -> Result<LoadedEnvironment, String> {
    let (mut file, length) = crate::files::open(path).map_err(|e| format!("cannot open file: {e}"))?;
    let mut head = [0u8; 16];
    let n = read_up_to(&mut file, &mut head).map_err(|e| format!("cannot read file: {e}"))?;
    let head = &head[..n];
    file.seek(SeekFrom::Start(0)).map_err(|e| format!("cannot read file: {e}"))?;
    let mut notices = Vec::new();
    let map = if head.starts_with(&EXR_MAGIC) {
        read_exr(file, length, &mut notices)?
    } else if head.starts_with(b"#?") {
        read_hdr(file, length, head.starts_with(b"#?RADIANCE"), &mut notices)?
    } else {
        return Err(format!(
            "not an OpenEXR or Radiance HDR file ({}); an environment must be an \
             equirectangular .exr or .hdr",
            describe_content(head)
        ));
    };
    check_shape(&map)?;
    sanitise(map, options, notices)
}

fn read_up_to(file: &mut File, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match file.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// A short guess of what a non-environment file is, for the error message.
fn describe_content(head: &[u8]) -> String {
    let known: [(&[u8], &str); 9] = [
        (b"\x89PNG\r\n\x1a\n", "it is a PNG image"),
        (b"\xff\xd8\xff", "it is a JPEG image"),
        (b"GIF8", "it is a GIF image"),
        (b"BM", "it looks like a BMP image"),
        (b"II*\0", "it is a TIFF image"),
        (b"MM\0*", "it is a TIFF image"),
        (b"RIFF", "it is a RIFF (e.g. WebP) file"),
        (b"glTF", "it is a binary glTF file"),
        (b"%PDF", "it is a PDF document"),
    ];
    if head.is_empty() {
        return "the file is empty".into();
    }
    for (magic, what) in known {
        if head.starts_with(magic) {
            return what.into();
        }
    }
    if head.iter().all(|&b| b.is_ascii_graphic() || b.is_ascii_whitespace()) {
        "it looks like a text file".into()
    } else {
        let hex: Vec<String> = head.iter().take(4).map(|b| format!("{b:02x}")).collect();
        format!("unrecognised first bytes {}", hex.join(" "))
    }
}

fn check_shape(map: &EnvironmentMap) -> Result<(), String> {
    let (w, h) = (map.width, map.height);
    if w == 0 || h == 0 {
        return Err(format!("the image is empty ({w}×{h})"));
    }
    if (w == 1 && h == 1) || w as u64 == 2 * h as u64 {
        Ok(())
    } else {
        Err(format!(
            "not an equirectangular map: {w}×{h} is not 2:1 (the width must be exactly twice \
             the height, or the map 1×1)"
        ))
    }
}

// ---------------------------------------------------------------------------------------------
// OpenEXR

/// One candidate colour layer: a part and a channel-name prefix within it.
struct Candidate {
    part: usize,
    prefix: String,
    /// Channel indices within the part: R, G, B (the same index thrice for grey).
    channels: [usize; 3],
    grey_from: Option<String>,
}

fn layer_label(part_name: Option<&str>, prefix: &str, parts: usize) -> String {
    let mut s = String::new();
    if let Some(n) = part_name.filter(|n| !n.is_empty()) {
        s.push_str(&format!("part '{n}'"));
    } else if parts > 1 {
        s.push_str("unnamed part");
    }
    if !prefix.is_empty() {
        if !s.is_empty() {
            s.push_str(", ");
        }
        s.push_str(&format!("layer '{prefix}'"));
    }
    if s.is_empty() {
        s.push_str("the default layer");
    }
    s
}

/// (part index, channel-name prefix, [(base name, channel index)]).
type ChannelGroup = (usize, String, Vec<(String, usize)>);

/// Decoded bytes one byte of an EXR file can hold at most: deflate's limit
/// (ZIP, PXR24 and the DWA codecs end in it; PIZ's coded runs stay below it),
/// 64 for RLE (a two-byte run of 128), 1 uncompressed.
fn exr_ratio(compression: exr::compression::Compression) -> u64 {
    use exr::compression::Compression;
    match compression {
        Compression::Uncompressed => 1,
        Compression::RLE => 64,
        _ => DEFLATE_RATIO,
    }
}

/// Deflate's densest coding: decoded bytes per byte.
const DEFLATE_RATIO: u64 = 1032;

/// Refuses an EXR whose parts or display window declare more texels than the file can hold.
pub(crate) fn check_exr_size(file: &File, length: u64) -> Result<(), String> {
    let meta = exr::meta::MetaData::read_from_buffered(BufReader::new(file), false)
        .map_err(|e| format!("cannot decode OpenEXR: {e}"))?;
    for header in &meta.headers {
        let (size, bytes) = (header.layer_size, header.channels.bytes_per_pixel as u64);
        let ratio = exr_ratio(header.compression);
        crate::files::check_declared(size.width() as u64, size.height() as u64, bytes, length, ratio)?;
        // The data is placed in the display window, black around it
        // (`place_in_display_window`): RGB f32 texels, held to the densest
        // coding, so that a header alone cannot ask for gigabytes.
        let display = header.shared_attributes.display_window.size;
        crate::files::check_declared(display.width() as u64, display.height() as u64, 12, length, DEFLATE_RATIO)
            .map_err(|e| format!("display window: {e}"))?;
    }
    Ok(())
}

/// One decoded part of a multi-part EXR, with every channel's samples.
type ExrLayer = exr::image::Layer<exr::image::AnyChannels<FlatSamples>>;

fn read_exr(mut file: File, length: u64, notices: &mut Vec<String>) -> Result<EnvironmentMap, String> {
    check_exr_size(&file, length)?;
    file.seek(SeekFrom::Start(0)).map_err(|e| format!("cannot read file: {e}"))?;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(BufReader::new(file))
        .map_err(|e| format!("cannot decode OpenEXR: {e}"))?;
    let display = image.attributes.display_window;
    let chromaticities = image.attributes.chromaticities;
    let mut layers = image.layer_data;

    let groups = channel_groups(&layers);
    let c = choose_layer(&groups, &layers)?;
    push_layer_notices(&groups, &layers, &c, notices);

    let layer = &mut layers[c.part];
    let (w, h) = check_layer(layer, &c)?;
    let texels = take_texels(layer, c.channels, w * h);
    let data_pos = layer.attributes.layer_position;
    drop(layers);
    let mut map = EnvironmentMap { width: w as u32, height: h as u32, texels };
    if let Some(ch) = chromaticities.filter(|_| c.grey_from.is_none()) {
        convert_primaries(&mut map, &ch, notices);
    }
    place_in_display_window(map, data_pos, &display, notices)
}

/// Groups every part's channels by prefix (everything before the last '.'): per part the
/// unprefixed layer first, then prefixed ones in name order.
fn channel_groups(layers: &[ExrLayer]) -> Vec<ChannelGroup> {
    let mut groups: Vec<ChannelGroup> = Vec::new();
    for (p, layer) in layers.iter().enumerate() {
        let mut local: Vec<(String, Vec<(String, usize)>)> = Vec::new();
        for (i, ch) in layer.channel_data.list.iter().enumerate() {
            let name = ch.name.to_string();
            let (prefix, base) = match name.rfind('.') {
                Some(k) => (name[..k].to_string(), name[k + 1..].to_string()),
                None => (String::new(), name.clone()),
            };
            match local.iter_mut().find(|(pf, _)| *pf == prefix) {
                Some((_, v)) => v.push((base, i)),
                None => local.push((prefix, vec![(base, i)])),
            }
        }
        local.sort_by(|a, b| (!a.0.is_empty(), &a.0).cmp(&(!b.0.is_empty(), &b.0)));
        groups.extend(local.into_iter().map(|(pf, v)| (p, pf, v)));
    }
    groups
}

/// The index of the first of `names` present among `chs`, matched exactly before ignoring case.
fn find_channel(chs: &[(String, usize)], names: &[&str]) -> Option<usize> {
    names.iter().find_map(|n| {
        chs.iter()
            .find(|(b, _)| b == n)
            .or_else(|| chs.iter().find(|(b, _)| b.eq_ignore_ascii_case(n)))
            .map(|&(_, i)| i)
    })
}

fn is_colour(base: &str) -> bool {
    !matches!(base.to_ascii_uppercase().as_str(), "A" | "ALPHA")
}

/// Picks the layer to read: the first with R, G, B; else the first with a luminance
/// channel Y (or L); else the first with exactly one (non-alpha) channel, read as grey.
fn choose_layer(groups: &[ChannelGroup], layers: &[ExrLayer]) -> Result<Candidate, String> {
    let rgb = groups.iter().find_map(|(p, pf, chs)| {
        let r = find_channel(chs, &["R", "red"])?;
        let g = find_channel(chs, &["G", "green"])?;
        let b = find_channel(chs, &["B", "blue"])?;
        Some(Candidate { part: *p, prefix: pf.clone(), channels: [r, g, b], grey_from: None })
    });
    let luminance = || {
        groups.iter().find_map(|(p, pf, chs)| {
            let y = find_channel(chs, &["Y", "L"])?;
            let name = chs.iter().find(|c| c.1 == y).unwrap().0.clone();
            Some(Candidate { part: *p, prefix: pf.clone(), channels: [y; 3], grey_from: Some(name) })
        })
    };
    let single = || {
        groups.iter().find(|(_, _, chs)| chs.len() == 1 && is_colour(&chs[0].0)).map(|(p, pf, chs)| Candidate {
            part: *p,
            prefix: pf.clone(),
            channels: [chs[0].1; 3],
            grey_from: Some(chs[0].0.clone()),
        })
    };
    rgb.or_else(luminance).or_else(single).ok_or_else(|| {
        let mut names: Vec<String> =
            layers.iter().flat_map(|l| l.channel_data.list.iter().map(|c| c.name.to_string())).collect();
        names.truncate(12);
        format!(
            "no colour channels: found {} but need R, G, B (optionally with a layer prefix) \
             or a single luminance channel",
            if names.is_empty() { "no channels".to_string() } else { format!("channels {}", names.join(", ")) }
        )
    })
}

/// Tells which layer is read when there is a choice (or it is not the default one), and
/// when a single channel stands in for colour.
fn push_layer_notices(groups: &[ChannelGroup], layers: &[ExrLayer], c: &Candidate, notices: &mut Vec<String>) {
    let parts = layers.len();
    let part_name = layers[c.part].attributes.layer_name.as_ref().map(|t| t.to_string());
    let label = layer_label(part_name.as_deref(), &c.prefix, parts);
    if groups.len() > 1 {
        let others: Vec<String> = groups
            .iter()
            .filter(|(p, pf, _)| !(*p == c.part && *pf == c.prefix))
            .map(|(p, pf, _)| {
                let n = layers[*p].attributes.layer_name.as_ref().map(|t| t.to_string());
                layer_label(n.as_deref(), pf, parts)
            })
            .take(8)
            .collect();
        notices.push(format!("the EXR has {} layers; using {label} and ignoring {}", groups.len(), others.join("; ")));
    } else if !c.prefix.is_empty() || part_name.is_some_and(|n| !n.is_empty()) {
        notices.push(format!("using EXR {label}"));
    }
    if let Some(name) = &c.grey_from {
        notices.push(format!("the EXR has no R, G, B channels; reading channel '{name}' of {label} as grey"));
    }
}

/// Refuses cube maps, sizes that overflow and subsampled channels; gives the layer's size.
fn check_layer(layer: &ExrLayer, c: &Candidate) -> Result<(usize, usize), String> {
    let (w, h) = (layer.size.x(), layer.size.y());
    if layer.attributes.environment_map == Some(exr::meta::attribute::EnvironmentMap::Cube) {
        return Err(format!(
            "a cube-face environment ({w}×{h}, envmap=cube); only equirectangular \
             (latitude-longitude) maps are supported"
        ));
    }
    if w > u32::MAX as usize || h > u32::MAX as usize || w.checked_mul(h).is_none() {
        return Err(format!("image too large ({w}×{h})"));
    }
    let n = w * h;
    for &i in &c.channels {
        let ch = &layer.channel_data.list[i];
        if ch.sampling.x() != 1 || ch.sampling.y() != 1 || ch.sample_data.len() != n {
            return Err(format!(
                "channel '{}' is subsampled ({}×{}), which is not supported for environments",
                ch.name,
                ch.sampling.x(),
                ch.sampling.y()
            ));
        }
    }
    Ok((w, h))
}

/// Converts the chosen channels to RGB f32 texels. Each channel is moved out and converted
/// in turn, so the decoded copy is freed channel by channel.
fn take_texels(layer: &mut ExrLayer, channels: [usize; 3], n: usize) -> Vec<[f32; 3]> {
    let mut texels = vec![[0.0f32; 3]; n];
    let mut done: Vec<usize> = Vec::new();
    for (slot, &i) in channels.iter().enumerate() {
        if done.contains(&i) {
            let src = done.iter().position(|&d| d == i).unwrap();
            for t in &mut texels {
                t[slot] = t[src];
            }
            done.push(i);
            continue;
        }
        let data = std::mem::replace(&mut layer.channel_data.list[i].sample_data, FlatSamples::F32(Vec::new()));
        match data {
            FlatSamples::F16(v) => {
                for (t, s) in texels.iter_mut().zip(v) {
                    t[slot] = s.to_f32();
                }
            }
            FlatSamples::F32(v) => {
                for (t, s) in texels.iter_mut().zip(v) {
                    t[slot] = s;
                }
            }
            FlatSamples::U32(v) => {
                for (t, s) in texels.iter_mut().zip(v) {
                    t[slot] = s as f32;
                }
            }
        }
        done.push(i);
    }
    texels
}

fn is_equirect_size(w: usize, h: usize) -> bool {
    (w == 1 && h == 1) || (h > 0 && w == 2 * h)
}

/// EXR pixels live in a data window that may be smaller than (or offset from) the display
/// window, e.g. when a writer cropped away black borders. The display window is the image's
/// frame; when it is an equirectangular size and differs from the data window, the data is
/// placed in it and the rest is black.
fn place_in_display_window(
    map: EnvironmentMap,
    data_pos: exr::math::Vec2<i32>,
    display: &exr::meta::attribute::IntegerBounds,
    notices: &mut Vec<String>,
) -> Result<EnvironmentMap, String> {
    let (w, h) = (map.width as usize, map.height as usize);
    let (dw, dh) = (display.size.x(), display.size.y());
    let same = (dw, dh) == (w, h) && display.position == data_pos;
    if same || !is_equirect_size(dw, dh) || dw.checked_mul(dh).is_none() {
        return Ok(map);
    }
    let ox = data_pos.x() as i64 - display.position.x() as i64;
    let oy = data_pos.y() as i64 - display.position.y() as i64;
    let mut texels = vec![[0.0f32; 3]; dw * dh];
    for row in 0..h as i64 {
        let y = row + oy;
        if y < 0 || y >= dh as i64 {
            continue;
        }
        for col in 0..w as i64 {
            let x = col + ox;
            if x < 0 || x >= dw as i64 {
                continue;
            }
            texels[y as usize * dw + x as usize] = map.texels[row as usize * w + col as usize];
        }
    }
    notices.push(format!(
        "the EXR data window ({w}×{h} at {},{}) differs from its display window ({dw}×{dh} at          {},{}); placed the pixels in the display window, black elsewhere",
        data_pos.x(),
        data_pos.y(),
        display.position.x(),
        display.position.y()
    ));
    Ok(EnvironmentMap { width: dw as u32, height: dh as u32, texels })
}

/// Rec. 709 / sRGB primaries and D65 white, the colour space the baker works in.
const REC709: [[f64; 2]; 4] = [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06], [0.3127, 0.3290]];

/// RGB → XYZ matrix (columns: the primaries scaled so that RGB = 1 is the white point).
fn rgb_to_xyz(p: &[[f64; 2]; 4]) -> Option<glam::DMat3> {
    let xyz = |c: [f64; 2]| (c[1].abs() > 1e-9).then(|| glam::DVec3::new(c[0] / c[1], 1.0, (1.0 - c[0] - c[1]) / c[1]));
    let m = glam::DMat3::from_cols(xyz(p[0])?, xyz(p[1])?, xyz(p[2])?);
    if m.determinant().abs() < 1e-9 {
        return None;
    }
    let s = m.inverse() * xyz(p[3])?;
    Some(glam::DMat3::from_cols(m.x_axis * s.x, m.y_axis * s.y, m.z_axis * s.z))
}

/// Converts RGB in the file's declared primaries to Rec. 709 (same white: no chromatic
/// adaptation beyond what the two white points imply, i.e. XYZ is kept as is).
fn convert_primaries(map: &mut EnvironmentMap, ch: &exr::meta::attribute::Chromaticities, notices: &mut Vec<String>) {
    let v = |c: exr::math::Vec2<f32>| [c.x() as f64, c.y() as f64];
    let file = [v(ch.red), v(ch.green), v(ch.blue), v(ch.white)];
    let close = file.iter().zip(&REC709).all(|(a, b)| (a[0] - b[0]).abs() < 2e-3 && (a[1] - b[1]).abs() < 2e-3);
    if close {
        return;
    }
    let (Some(src), Some(dst)) = (rgb_to_xyz(&file), rgb_to_xyz(&REC709)) else {
        notices.push("ignored the EXR's chromaticities: they are degenerate".into());
        return;
    };
    let m = dst.inverse() * src;
    for t in &mut map.texels {
        let c = m * glam::DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64);
        *t = [c.x as f32, c.y as f32, c.z as f32];
    }
    notices.push(format!(
        "converted the EXR's RGB primaries (r {:.4},{:.4} g {:.4},{:.4} b {:.4},{:.4} white          {:.4},{:.4}) to Rec. 709",
        file[0][0], file[0][1], file[1][0], file[1][1], file[2][0], file[2][1], file[3][0],
        file[3][1]
    ));
}

// ---------------------------------------------------------------------------------------------
// Radiance RGBE

/// Decoded bytes (RGB f32) one byte of a Radiance file can hold at most:
/// its run-length scanlines pack 127 texels into 2 bytes per channel. The
/// old, denser run-length scheme of files before 1991 is refused past it.
const HDR_RATIO: u64 = 127 * 12 / 8 + 1;

fn read_hdr(
    file: File,
    length: u64,
    strict_signature: bool,
    notices: &mut Vec<String>,
) -> Result<EnvironmentMap, String> {
    use image::ImageDecoder;
    use image::codecs::hdr::HdrDecoder;
    let reader = BufReader::new(file);
    // Files signed `#?RGBE` (or other `#?` variants) are read leniently; the signature line
    // then counts as a comment.
    let decoder = if strict_signature { HdrDecoder::new(reader) } else { HdrDecoder::new_nonstrict(reader) }
        .map_err(|e| format!("cannot decode Radiance HDR: {e}"))?;
    let meta = decoder.metadata();
    let (w, h) = decoder.dimensions();
    crate::files::check_declared(w as u64, h as u64, 12, length, HDR_RATIO)?;
    let n = (w as usize).checked_mul(h as usize).ok_or_else(|| format!("image too large ({w}×{h})"))?;
    let mut texels = vec![[0.0f32; 3]; n];
    decoder
        .read_image(bytemuck::cast_slice_mut(&mut texels))
        .map_err(|e| format!("cannot decode Radiance HDR: {e}"))?;
    let exposure = meta.exposure.unwrap_or(1.0);
    let cc = meta.color_correction.unwrap_or((1.0, 1.0, 1.0));
    let scale = [cc.0 * exposure, cc.1 * exposure, cc.2 * exposure];
    if scale != [1.0; 3] {
        if scale.iter().all(|s| s.is_finite() && *s > 0.0) {
            for t in &mut texels {
                for c in 0..3 {
                    t[c] /= scale[c];
                }
            }
            notices.push(format!(
                "divided the Radiance EXPOSURE/COLORCORR factors out of the pixels \
                 (R {:.4}, G {:.4}, B {:.4})",
                scale[0], scale[1], scale[2]
            ));
        } else {
            notices.push(format!("ignored unusable Radiance EXPOSURE/COLORCORR factors ({:?})", scale));
        }
    }
    Ok(EnvironmentMap { width: w, height: h, texels })
}

// ---------------------------------------------------------------------------------------------
// Sanitising

fn sanitise(
    mut map: EnvironmentMap,
    options: &EnvLoadOptions,
    mut notices: Vec<String>,
) -> Result<LoadedEnvironment, String> {
    replace_nonfinite(&mut map, options, &mut notices)?;
    let (neg_count, removed) = clamp_negative(&mut map);
    let integral = map.integral();
    if neg_count > 0 {
        let rel: Vec<String> = ["R", "G", "B"]
            .iter()
            .enumerate()
            .map(|(c, name)| {
                if integral[c] > 0.0 {
                    format!("{name} {:.2e}", removed[c] / integral[c])
                } else {
                    format!("{name} {:.2e} (absolute)", removed[c])
                }
            })
            .collect();
        notices.push(format!(
            "clamped {neg_count} negative texel values to zero (lossy EXR codecs leave small \
             ones); energy removed relative to the map's integral: {}",
            rel.join(", ")
        ));
    }
    if integral.iter().all(|&v| v == 0.0) {
        notices.push("warning: the environment is black (its integral is zero)".into());
    }
    Ok(LoadedEnvironment { map, notices })
}

/// Non-finite values: an error unless clamping is enabled, then NaN and -inf become 0 and
/// +inf the largest finite value, with a warning that says where.
fn replace_nonfinite(
    map: &mut EnvironmentMap,
    options: &EnvLoadOptions,
    notices: &mut Vec<String>,
) -> Result<(), String> {
    // The common case, every value finite, in one branch-free pass.
    let values: &[f32] = bytemuck::cast_slice(&map.texels);
    if values.iter().fold(true, |finite, v| finite & v.is_finite()) {
        return Ok(());
    }
    let w = map.width as usize;
    let mut nan = 0usize;
    let mut pos_inf = 0usize;
    let mut neg_inf = 0usize;
    let mut first: Vec<(usize, usize)> = Vec::new();
    let mut max_finite = 0.0f32;
    for (i, t) in map.texels.iter().enumerate() {
        let mut bad = false;
        for &v in t {
            if v.is_nan() {
                nan += 1;
                bad = true;
            } else if v == f32::INFINITY {
                pos_inf += 1;
                bad = true;
            } else if v == f32::NEG_INFINITY {
                neg_inf += 1;
                bad = true;
            } else if v > max_finite {
                max_finite = v;
            }
        }
        if bad && first.len() < LIST_FIRST {
            first.push((i % w, i / w));
        }
    }
    let nonfinite = nan + pos_inf + neg_inf;
    if nonfinite > 0 {
        let kinds = [(nan, "NaN"), (pos_inf, "+inf"), (neg_inf, "-inf")]
            .iter()
            .filter(|(n, _)| *n > 0)
            .map(|(n, k)| format!("{n} {k}"))
            .collect::<Vec<_>>()
            .join(", ");
        let at = first.iter().map(|(c, r)| format!("({c},{r})")).collect::<Vec<_>>().join(", ");
        let more = if nonfinite > first.len() { ", …" } else { "" };
        if !options.clamp_nonfinite {
            return Err(format!(
                "{nonfinite} non-finite texel values ({kinds}) at (col,row) {at}{more}; \
                 enable non-finite clamping to load it anyway (NaN and -inf become 0, +inf the \
                 largest finite value)"
            ));
        }
        for t in &mut map.texels {
            for v in t.iter_mut() {
                if v.is_nan() || *v == f32::NEG_INFINITY {
                    *v = 0.0;
                } else if *v == f32::INFINITY {
                    *v = max_finite;
                }
            }
        }
        notices.push(format!(
            "warning: replaced {nonfinite} non-finite texel values ({kinds}; first at (col,row) \
             {at}{more}): NaN and -inf by 0, +inf by the largest finite value {max_finite}"
        ));
    }
    Ok(())
}

/// Clamps negative channel values to 0 (and −0 to +0); gives how many there were and the
/// energy removed per channel (value × solid angle). Runs after `replace_nonfinite`: no NaN
/// is left, which this would turn into 0.
fn clamp_negative(map: &mut EnvironmentMap) -> (usize, [f64; 3]) {
    let w = map.width as usize;
    let mut neg_count = 0usize;
    let mut removed = [0.0f64; 3];
    let omegas: Vec<f64> = (0..map.height).map(|r| map.row_solid_angle(r)).collect();
    for (row, texels) in map.texels.chunks_exact_mut(w).enumerate() {
        let mut row_removed = [0.0f64; 3];
        for t in texels {
            for c in 0..3 {
                // Branch-free (adding +0 leaves a sum as it was); −0 becomes +0 too.
                let negative = t[c] < 0.0;
                neg_count += negative as usize;
                row_removed[c] += if negative { -(t[c] as f64) } else { 0.0 };
                t[c] = if t[c] > 0.0 { t[c] } else { 0.0 };
            }
        }
        if row_removed != [0.0; 3] {
            let omega = omegas[row];
            for c in 0..3 {
                removed[c] += row_removed[c] * omega;
            }
        }
    }
    (neg_count, removed)
}
