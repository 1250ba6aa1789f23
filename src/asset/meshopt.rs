//! EXT_meshopt_compression (and KHR_meshopt_compression, its ratified form):
//! buffer views stored compressed by meshoptimizer (gltfpack `-c`). Each
//! compressed view names where its compressed bytes are, and itself points
//! into a fallback buffer that holds no data but has the uncompressed
//! layout. Loading decodes every such view into its place in the fallback
//! buffer and drops the extension, so the rest of bake (and the output)
//! sees a plain, uncompressed asset.

use anyhow::{Context, Result, anyhow, bail, ensure};
use serde_json::Value;

use super::{drop_extensions, remove_extension};

pub const EXTENSIONS: [&str; 2] = ["EXT_meshopt_compression", "KHR_meshopt_compression"];

/// The most a fallback buffer may declare: it is allocated before decoding.
const MAX_FALLBACK_BYTES: u64 = 4 << 30;

/// Whether buffer `buffer` of `json` is a fallback buffer (no data of its own).
pub fn is_fallback(json: &Value, buffer: usize) -> bool {
    EXTENSIONS.iter().any(|name| {
        json.pointer(&format!("/buffers/{buffer}/extensions/{name}/fallback")).and_then(Value::as_bool) == Some(true)
    })
}

/// Decodes every compressed buffer view of `json` into `buffers` (index for
/// index with `json`'s buffers; fallback buffers empty on entry) and removes
/// the extension from the views, the buffers and the extension lists.
/// Returns how many views it decoded.
pub fn decode(json: &mut Value, buffers: &mut [Vec<u8>]) -> Result<usize> {
    let mut decoded = 0;
    let view_count = json.get("bufferViews").and_then(Value::as_array).map_or(0, Vec::len);
    for v in 0..view_count {
        let Some(name) = EXTENSIONS.iter().find(|name| json["bufferViews"][v]["extensions"].get(**name).is_some())
        else {
            continue;
        };
        let view = &json["bufferViews"][v];
        let target = Slot::of(view, buffers.len())?;
        let bytes = decode_view(&view["extensions"][*name], buffers).with_context(|| format!("buffer view {v}"))?;
        ensure!(
            bytes.len() == target.length,
            "buffer view {v}: decodes to {} bytes where its byteLength is {}",
            bytes.len(),
            target.length
        );
        let buffer = &mut buffers[target.buffer];
        if buffer.is_empty() && is_fallback(json, target.buffer) {
            let declared = json["buffers"][target.buffer]["byteLength"].as_u64().unwrap_or(0);
            ensure!(declared <= MAX_FALLBACK_BYTES, "buffer {} declares {declared} bytes", target.buffer);
            buffer.resize(declared as usize, 0);
        }
        let place = buffer
            .get_mut(target.offset..target.offset + target.length)
            .ok_or_else(|| anyhow!("buffer view {v} lies past the end of buffer {}", target.buffer))?;
        place.copy_from_slice(&bytes);
        remove_extension(&mut json["bufferViews"][v], name);
        decoded += 1;
    }
    if decoded > 0 {
        for b in 0..buffers.len() {
            for name in EXTENSIONS {
                remove_extension(&mut json["buffers"][b], name);
            }
        }
        drop_extensions(json, &EXTENSIONS);
    }
    Ok(decoded)
}

/// Where a buffer view's uncompressed bytes go.
struct Slot {
    buffer: usize,
    offset: usize,
    length: usize,
}

impl Slot {
    fn of(view: &Value, buffers: usize) -> Result<Slot> {
        let field = |key: &str, default: Option<u64>| {
            view.get(key).and_then(Value::as_u64).or(default).ok_or_else(|| anyhow!("buffer view has no {key}"))
        };
        let buffer = field("buffer", None)? as usize;
        ensure!(buffer < buffers, "buffer view names buffer {buffer}, which does not exist");
        Ok(Slot { buffer, offset: field("byteOffset", Some(0))? as usize, length: field("byteLength", None)? as usize })
    }
}

/// The uncompressed bytes of one view from its extension object.
fn decode_view(extension: &Value, buffers: &[Vec<u8>]) -> Result<Vec<u8>> {
    let field = |key: &str| extension.get(key).and_then(Value::as_u64).ok_or_else(|| anyhow!("no {key}"));
    let source = Slot {
        buffer: field("buffer")? as usize,
        offset: extension.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize,
        length: field("byteLength")? as usize,
    };
    let stride = field("byteStride")? as usize;
    let count = field("count")? as usize;
    let data = buffers
        .get(source.buffer)
        .and_then(|b| b.get(source.offset..source.offset.checked_add(source.length)?))
        .ok_or_else(|| anyhow!("its compressed bytes lie past the end of buffer {}", source.buffer))?;
    let size = count.checked_mul(stride).filter(|&s| s as u64 <= MAX_FALLBACK_BYTES);
    let size = size.ok_or_else(|| anyhow!("{count} elements of {stride} bytes are too many"))?;
    let mode = extension.get("mode").and_then(Value::as_str).unwrap_or("");
    let filter = extension.get("filter").and_then(Value::as_str).unwrap_or("NONE");
    match mode {
        "ATTRIBUTES" => {
            ensure!(
                stride.is_multiple_of(4) && (4..=256).contains(&stride),
                "byteStride {stride} is not 4 to 256 by 4"
            );
            let mut bytes = vec![0u8; size];
            // SAFETY: `bytes` holds `count` elements of `stride` bytes; the
            // decoder reads only `data` and is safe on untrusted input.
            let code = unsafe {
                ::meshopt::ffi::meshopt_decodeVertexBuffer(
                    bytes.as_mut_ptr().cast(),
                    count,
                    stride,
                    data.as_ptr(),
                    data.len(),
                )
            };
            ensure!(code == 0, "the compressed vertex data is corrupt (meshoptimizer error {code})");
            unfilter(&mut bytes, count, stride, filter)?;
            Ok(bytes)
        }
        "TRIANGLES" | "INDICES" => {
            ensure!(filter == "NONE", "filter {filter} on indices");
            let indices: Vec<u32> = if mode == "TRIANGLES" {
                ::meshopt::decode_index_buffer::<u32>(data, count)
            } else {
                ::meshopt::decode_index_sequence::<u32>(data, count)
            }
            .map_err(|e| anyhow!("the compressed indices are corrupt ({e:?})"))?;
            match stride {
                2 => Ok(indices.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect()),
                4 => Ok(indices.iter().flat_map(|&i| i.to_le_bytes()).collect()),
                _ => bail!("index byteStride {stride} is neither 2 nor 4"),
            }
        }
        other => bail!("unknown mode '{other}'"),
    }
}

/// Undoes the view's filter on decoded vertex data, in place.
fn unfilter(bytes: &mut [u8], count: usize, stride: usize, filter: &str) -> Result<()> {
    use ::meshopt::ffi;
    let pointer = bytes.as_mut_ptr().cast();
    // SAFETY: each filter rewrites `count` elements of `stride` bytes inside
    // `bytes`, whose strides were checked to be those the filter takes.
    match filter {
        "NONE" => {}
        "OCTAHEDRAL" => {
            ensure!(stride == 4 || stride == 8, "OCTAHEDRAL filter on byteStride {stride}");
            unsafe { ffi::meshopt_decodeFilterOct(pointer, count, stride) }
        }
        "QUATERNION" => {
            ensure!(stride == 8, "QUATERNION filter on byteStride {stride}");
            unsafe { ffi::meshopt_decodeFilterQuat(pointer, count, stride) }
        }
        "EXPONENTIAL" => unsafe { ffi::meshopt_decodeFilterExp(pointer, count, stride) },
        "COLOR" => {
            ensure!(stride == 4 || stride == 8, "COLOR filter on byteStride {stride}");
            unsafe { ffi::meshopt_decodeFilterColor(pointer, count, stride) }
        }
        other => bail!("unknown filter '{other}'"),
    }
    Ok(())
}
