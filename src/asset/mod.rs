//! The input glTF asset as it is on disk: validated document, the raw JSON
//! (so export can carry every field through, known or not), and the bytes of
//! every buffer. Import reads meshes from it; export rewrites it.
//!
//! External files are resolved relative to the input's folder and must stay
//! inside it: a URI that climbs out (`../secret.bin`, an absolute path) is
//! refused, so a build step never reads files the asset does not own.

pub mod accessor;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use base64::Engine as _;

/// Extensions whose meaning `bake` understands or can safely carry through
/// when an input lists them in `extensionsRequired`.
const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_materials_emissive_strength",
    "KHR_materials_unlit",
    "KHR_texture_transform",
    "KHR_mesh_quantization",
    "KHR_materials_variants",
    "KHR_texture_basisu",
];

/// A glTF asset loaded from `.gltf` or `.glb`.
pub struct SourceAsset {
    /// Where it came from (for messages).
    pub path: PathBuf,
    /// The validated document (structure, indices in range).
    pub document: gltf::Document,
    /// The JSON exactly as written, unknown fields and extensions included.
    pub json: serde_json::Value,
    /// Bytes of each buffer, index for index.
    pub buffers: Vec<Vec<u8>>,
}

impl SourceAsset {
    /// Reads and validates a `.gltf` or `.glb` file and every buffer it uses.
    pub fn load(path: &Path) -> Result<SourceAsset> {
        let bytes = std::fs::read(path).map_err(|e| anyhow!("cannot read: {e}"))?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::from_bytes(path, &bytes, Some(base))
    }

    /// Parses an asset held in memory. `base` is the folder external URIs are
    /// resolved against; `None` refuses external files.
    pub fn from_bytes(path: &Path, bytes: &[u8], base: Option<&Path>) -> Result<SourceAsset> {
        let (json_bytes, blob) = if bytes.starts_with(b"glTF") {
            let glb = gltf::binary::Glb::from_slice(bytes).map_err(|e| anyhow!("not a valid .glb: {e}"))?;
            (glb.json.into_owned(), glb.bin.map(|b| b.into_owned()))
        } else {
            if !looks_like_json(bytes) {
                bail!("not a glTF file (neither .glb binary nor JSON)");
            }
            (bytes.to_vec(), None)
        };
        let json: serde_json::Value =
            serde_json::from_slice(&json_bytes).map_err(|e| anyhow!("invalid glTF JSON: {e}"))?;
        check_required_extensions(&json)?;
        let root: gltf::json::Root =
            serde_json::from_value(json.clone()).map_err(|e| anyhow!("invalid glTF JSON: {e}"))?;
        let document =
            gltf::Document::from_json(root).map_err(|e| anyhow!("invalid glTF: {}", describe_validation(&e)))?;

        let mut buffers = Vec::new();
        for buffer in document.buffers() {
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => blob
                    .clone()
                    .ok_or_else(|| anyhow!("buffer {} refers to a GLB binary chunk that is missing", buffer.index()))?,
                gltf::buffer::Source::Uri(uri) => {
                    resolve_uri(uri, base).with_context(|| format!("buffer {}", buffer.index()))?
                }
            };
            if data.len() < buffer.length() {
                bail!(
                    "buffer {} is truncated: {} bytes of the declared {}",
                    buffer.index(),
                    data.len(),
                    buffer.length()
                );
            }
            buffers.push(data);
        }
        Ok(SourceAsset { path: path.to_path_buf(), document, json, buffers })
    }

    /// The encoded bytes (PNG, JPEG, ...) of image `index` and its MIME type if known.
    pub fn image_bytes(&self, index: usize) -> Result<(Vec<u8>, Option<String>)> {
        let image = self.document.images().nth(index).ok_or_else(|| anyhow!("image {index} does not exist"))?;
        match image.source() {
            gltf::image::Source::View { view, mime_type } => {
                let bytes = self.view_bytes(&view)?;
                Ok((bytes.to_vec(), Some(mime_type.to_string())))
            }
            gltf::image::Source::Uri { uri, mime_type } => {
                let base = self.path.parent().unwrap_or(Path::new("."));
                let bytes = resolve_uri(uri, Some(base)).with_context(|| format!("image {index}"))?;
                Ok((bytes, mime_type.map(str::to_string)))
            }
        }
    }

    /// The bytes a buffer view covers, bounds-checked.
    pub fn view_bytes(&self, view: &gltf::buffer::View) -> Result<&[u8]> {
        let buffer = &self.buffers[view.buffer().index()];
        let end = view.offset().checked_add(view.length()).filter(|&end| end <= buffer.len());
        match end {
            Some(end) => Ok(&buffer[view.offset()..end]),
            None => bail!(
                "bufferView {} ({} bytes at {}) runs past the end of buffer {} ({} bytes)",
                view.index(),
                view.length(),
                view.offset(),
                view.buffer().index(),
                buffer.len()
            ),
        }
    }
}

fn looks_like_json(bytes: &[u8]) -> bool {
    let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    text.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{')
}

fn check_required_extensions(json: &serde_json::Value) -> Result<()> {
    let Some(required) = json.get("extensionsRequired").and_then(|v| v.as_array()) else {
        return Ok(());
    };
    for name in required.iter().filter_map(|v| v.as_str()) {
        match name {
            "KHR_draco_mesh_compression" | "EXT_meshopt_compression" | "KHR_meshopt_compression" => bail!(
                "meshes are compressed with {name}, which bake does not decode; \
                 decompress them first, e.g. `npx @gltf-transform/cli cp IN.glb PLAIN.glb`"
            ),
            _ if SUPPORTED_REQUIRED.contains(&name) => {}
            _ => bail!("requires the extension {name}, which bake does not support"),
        }
    }
    Ok(())
}

/// Reads a buffer or image URI: a `data:` URI, or a relative file path that
/// must stay inside `base`.
fn resolve_uri(uri: &str, base: Option<&Path>) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (header, payload) = rest.split_once(',').ok_or_else(|| anyhow!("malformed data URI"))?;
        if !header.ends_with(";base64") {
            bail!("data URI is not base64-encoded");
        }
        return base64::engine::general_purpose::STANDARD
            .decode(payload.trim())
            .map_err(|e| anyhow!("data URI is not valid base64: {e}"));
    }
    if uri.contains("://") {
        bail!("refusing to fetch '{uri}': only files beside the asset and data URIs are read");
    }
    let base = base.ok_or_else(|| anyhow!("'{uri}' is an external file, but the asset was given without a folder"))?;
    let relative = percent_decode(uri)?;
    let relative = Path::new(&relative);
    if relative.is_absolute()
        || relative.components().any(|c| matches!(c, std::path::Component::ParentDir | std::path::Component::Prefix(_)))
    {
        bail!("refusing '{uri}': it points outside the asset's folder");
    }
    let path = base.join(relative);
    std::fs::read(&path).map_err(|e| anyhow!("cannot read '{}': {e}", path.display()))
}

/// Decodes `%XX` escapes (URIs in glTF are percent-encoded).
pub(crate) fn percent_decode(uri: &str) -> Result<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes.get(i + 1..i + 3).and_then(|h| std::str::from_utf8(h).ok());
            let value = hex.and_then(|h| u8::from_str_radix(h, 16).ok());
            out.push(value.ok_or_else(|| anyhow!("bad percent-escape in URI '{uri}'"))?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| anyhow!("URI '{uri}' is not UTF-8 after decoding"))
}

/// The first few validation problems, on one line.
fn describe_validation(error: &gltf::Error) -> String {
    match error {
        gltf::Error::Validation(list) => {
            let mut parts: Vec<String> =
                list.iter().take(3).map(|(path, e)| format!("{} {e}", path.as_str())).collect();
            if list.len() > 3 {
                parts.push(format!("and {} more", list.len() - 3));
            }
            parts.join("; ")
        }
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_escapes_decode() {
        assert_eq!(percent_decode("a%20b.bin").unwrap(), "a b.bin");
        assert!(percent_decode("a%2").is_err());
    }

    #[test]
    fn uris_outside_the_folder_are_refused() {
        let base = Path::new("/tmp");
        for uri in ["../etc/passwd", "/etc/passwd", "a/../../b.bin", "http://example.com/x.bin"] {
            let error = resolve_uri(uri, Some(base)).unwrap_err().to_string();
            assert!(error.contains("refus"), "{uri}: {error}");
        }
    }

    #[test]
    fn data_uris_decode() {
        assert_eq!(resolve_uri("data:application/octet-stream;base64,AAEC", None).unwrap(), vec![0, 1, 2]);
    }
}
