//! The input glTF asset as it is on disk: validated document, the raw JSON
//! (so export can carry every field through, known or not), and the bytes of
//! every buffer. Import reads meshes from it; export rewrites it.
//!
//! External files are resolved relative to the input's folder and must stay
//! inside it: a URI that climbs out (`../secret.bin`, an absolute path) is
//! refused, and so is one whose resolved path (through symbolic links) lies
//! outside, so a build step never reads files the asset does not own.

pub mod accessor;
pub mod draco;
pub mod hierarchy;
pub mod instancing;
pub mod ktx2;
pub mod meshopt;
pub mod morph;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail, ensure};
use base64::Engine as _;

/// Extensions whose meaning `bake` understands or can safely carry through
/// when an input lists them in `extensionsRequired`.
const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_materials_emissive_strength",
    "KHR_materials_unlit",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_texture_transform",
    "KHR_mesh_quantization",
    "KHR_materials_variants",
    IMAGE_FORMAT_EXTENSIONS[0],
    IMAGE_FORMAT_EXTENSIONS[1],
    IMAGE_FORMAT_EXTENSIONS[2],
    instancing::EXTENSION,
    meshopt::EXTENSIONS[0],
    meshopt::EXTENSIONS[1],
    draco::EXTENSION,
];

/// Extensions that give a texture an image in another format: bake decodes
/// WebP and KTX2 (Basis Universal) and carries AVIF through.
const IMAGE_FORMAT_EXTENSIONS: &[&str] = &["EXT_texture_webp", "EXT_texture_avif", "KHR_texture_basisu"];

/// Names of the two KHR_materials_variants variants a bake appends, in that
/// order (README, "Using the lightmap in an engine"). Export writes them;
/// import reads them back to find the material a baked file had before.
pub const VARIANT_BAKED: &str = "baked";
pub const VARIANT_LIGHTMAPPED: &str = "pbr+lightmap";

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
        let bytes = crate::files::read(path).map_err(|e| anyhow!("cannot read: {e}"))?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::from_bytes(path, &bytes, Some(base))
    }

    /// Parses an asset held in memory. `base` is the folder external URIs are
    /// resolved against; `None` refuses external files.
    pub fn from_bytes(path: &Path, bytes: &[u8], base: Option<&Path>) -> Result<SourceAsset> {
        let (json_bytes, blob) = if bytes.starts_with(b"glTF") {
            let (json, bin) = split_glb(bytes)?;
            (json.to_vec(), bin.map(<[u8]>::to_vec))
        } else {
            if !looks_like_json(bytes) {
                bail!("not a glTF file (neither .glb binary nor JSON)");
            }
            (bytes.to_vec(), None)
        };
        let json: serde_json::Value =
            serde_json::from_slice(&json_bytes).map_err(|e| anyhow!("invalid glTF JSON: {e}"))?;
        check_required_extensions(&json)?;
        let document = validate(&json)?;

        let mut json = json;
        let mut buffers = Vec::new();
        for buffer in document.buffers() {
            let mut data = match buffer.source() {
                // Filled by decoding the views that point into it.
                _ if meshopt::is_fallback(&json, buffer.index()) => Vec::new(),
                gltf::buffer::Source::Bin => blob
                    .clone()
                    .ok_or_else(|| anyhow!("buffer {} refers to a GLB binary chunk that is missing", buffer.index()))?,
                gltf::buffer::Source::Uri(uri) => {
                    resolve_uri(uri, base).with_context(|| format!("buffer {}", buffer.index()))?
                }
            };
            if data.len() < buffer.length() && !meshopt::is_fallback(&json, buffer.index()) {
                bail!(
                    "buffer {} is truncated: {} bytes of the declared {}",
                    buffer.index(),
                    data.len(),
                    buffer.length()
                );
            }
            // The buffer is its declared bytes (a GLB's BIN chunk may pad it
            // to 4): a view reaching past them is refused (`view_bytes`), as
            // the spec and its validator ask, not read from the padding or
            // whatever the file holds beyond.
            data.truncate(buffer.length());
            buffers.push(data);
        }
        let decoded = meshopt::decode(&mut json, &mut buffers)? + draco::decode(&mut json, &mut buffers)?;
        let document = if decoded == 0 { document } else { validate(&json)? };
        // Images are decoded or copied later; a missing or refused file is an
        // error now, before any baking, not at export.
        for image in document.images() {
            if let gltf::image::Source::Uri { uri, .. } = image.source()
                && !uri.starts_with("data:")
            {
                let path = external_path(uri, base).with_context(|| format!("image {}", image.index()))?;
                let file = std::fs::metadata(&path).map_err(|e| anyhow!("cannot read '{}': {e}", path.display()));
                file.and_then(|m| if m.is_file() { Ok(()) } else { bail!("'{}' is not a file", path.display()) })
                    .with_context(|| format!("image {}", image.index()))?;
            }
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

/// What the gltf crate assumes but does not validate, found by
/// tests/fuzz_import.rs: its validation reads each primitive's POSITION
/// accessor by index before checking that it exists, and `Image::source`
/// unwraps an image's `uri`, or the `mimeType` of an image in a buffer view.
/// Either way a malformed file panics; check them first.
fn check_unvalidated(root: &gltf::json::Root) -> Result<()> {
    for (i, image) in root.images.iter().enumerate() {
        match (&image.buffer_view, &image.uri, &image.mime_type) {
            (Some(_), None, Some(_)) | (None, Some(_), _) => {}
            (Some(_), None, None) => bail!("invalid glTF: images[{i}] is in a bufferView but has no mimeType"),
            (None, None, _) => bail!("invalid glTF: images[{i}] has neither a uri nor a bufferView"),
            (Some(_), Some(_), _) => bail!("invalid glTF: images[{i}] has both a uri and a bufferView"),
        }
    }
    let positions = gltf::json::validation::Checked::Valid(gltf::json::mesh::Semantic::Positions);
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(index) = primitive.attributes.get(&positions)
                && index.value() >= root.accessors.len()
            {
                bail!(
                    "invalid glTF: meshes[{m}].primitives[{p}].attributes.POSITION is accessor {}, but there are {} accessors",
                    index.value(),
                    root.accessors.len()
                );
            }
        }
    }
    Ok(())
}

/// An image named by a texture's image-format extension exists (the gltf
/// crate does not know these extensions, so it cannot check them).
fn check_texture_extension_sources(json: &serde_json::Value) -> Result<()> {
    let images = json.get("images").and_then(serde_json::Value::as_array).map_or(0, Vec::len);
    let textures = json.get("textures").and_then(serde_json::Value::as_array).into_iter().flatten();
    for (t, texture) in textures.enumerate() {
        let extensions = texture.get("extensions").and_then(serde_json::Value::as_object).into_iter().flatten();
        for (name, extension) in extensions.filter(|(name, _)| IMAGE_FORMAT_EXTENSIONS.contains(&name.as_str())) {
            match extension.get("source").and_then(serde_json::Value::as_u64) {
                Some(source) if (source as usize) < images => {}
                Some(source) => {
                    bail!(
                        "invalid glTF: textures[{t}].extensions.{name}.source is {source}, but there are {images} images"
                    )
                }
                None => bail!("invalid glTF: textures[{t}].extensions.{name} has no source"),
            }
        }
    }
    Ok(())
}

/// The validated document of `json`, whose required extensions are vetted
/// (`check_required_extensions`): the gltf crate refuses every one it does
/// not implement itself, quantization and instancing included, which bake
/// reads, so it validates the rest without the list.
fn validate(json: &serde_json::Value) -> Result<gltf::Document> {
    let mut vetted = json.clone();
    vetted.as_object_mut().map(|root| root.remove("extensionsRequired"));
    let root: gltf::json::Root = serde_json::from_value(vetted).map_err(|e| anyhow!("invalid glTF JSON: {e}"))?;
    check_unvalidated(&root)?;
    check_texture_extension_sources(json)?;
    use gltf::json::validation::{Error, Validate};
    let mut errors = Vec::new();
    root.validate(&root, gltf::json::Path::new, &mut |path, error| errors.push((path(), error)));
    // An accessor with neither a buffer view nor sparse data is all zeros
    // (glTF 2.0, "Accessors"), which the gltf crate reports as missing:
    // `accessor::packed_bytes` fills it (within a bound), and a Draco
    // primitive's accessors are filled when it is decoded.
    errors.retain(|(path, error)| !(*error == Error::Missing && is_accessor_view(path.as_str())));
    if !errors.is_empty() {
        bail!("invalid glTF: {}", describe_validation(&gltf::Error::Validation(errors)));
    }
    Ok(gltf::Document::from_json_without_validation(root))
}

/// Whether `path` is `accessors[N].bufferView`.
fn is_accessor_view(path: &str) -> bool {
    path.strip_prefix("accessors[")
        .and_then(|rest| rest.strip_suffix("].bufferView"))
        .is_some_and(|index| index.parse::<usize>().is_ok())
}

/// Removes extension `name` from a glTF object (a node, a buffer view, ...),
/// and its `extensions` object when that is left empty.
pub fn remove_extension(object: &mut serde_json::Value, name: &str) {
    let Some(extensions) = object.get_mut("extensions").and_then(serde_json::Value::as_object_mut) else { return };
    extensions.remove(name);
    if extensions.is_empty() {
        object.as_object_mut().map(|o| o.remove("extensions"));
    }
}

/// Removes `names` from a document's `extensionsUsed` and
/// `extensionsRequired`, and a list left empty (glTF forbids empty ones).
pub fn drop_extensions(json: &mut serde_json::Value, names: &[&str]) {
    for list in ["extensionsUsed", "extensionsRequired"] {
        if let Some(listed) = json.get_mut(list).and_then(serde_json::Value::as_array_mut) {
            listed.retain(|n| !names.iter().any(|name| n == name));
            if listed.is_empty() {
                json.as_object_mut().map(|o| o.remove(list));
            }
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
        if !SUPPORTED_REQUIRED.contains(&name) {
            bail!("requires the extension {name}, which bake does not support");
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
    let path = external_path(uri, base)?;
    crate::files::read(&path).map_err(|e| anyhow!("cannot read '{}': {e}", path.display()))
}

/// The file a relative URI names inside `base`, refusing URIs that leave it
/// (`..`, absolute paths, a symbolic link that resolves outside) or name
/// another scheme.
fn external_path(uri: &str, base: Option<&Path>) -> Result<PathBuf> {
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
    // The policy must hold for the path the file system resolves too.
    if !crate::files::resolves_inside(&path, base) {
        bail!("refusing '{uri}': it points outside the asset's folder (through a symbolic link)");
    }
    Ok(path)
}

/// Splits a `.glb` into its JSON chunk and its BIN chunk (if any), saying
/// exactly what is cut short or malformed. Chunks after BIN are ignored, as
/// the glTF spec allows.
fn split_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>)> {
    let u32_at = |at: usize| bytes.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    let (Some(version), Some(declared)) = (u32_at(4), u32_at(8)) else {
        bail!("truncated .glb: {} bytes, shorter than the 12-byte header", bytes.len());
    };
    ensure!(version == 2, "unsupported .glb version {version} (bake reads glTF 2.0)");
    ensure!(
        declared <= bytes.len(),
        "truncated .glb: the header declares {declared} bytes but the file has {}",
        bytes.len()
    );
    let mut chunks: Vec<(&[u8], &[u8])> = Vec::new();
    let mut at = 12;
    while at < declared && chunks.len() < 2 {
        ensure!(at + 8 <= declared, "truncated .glb: the chunk header at byte {at} is cut off");
        let (length, kind) = (u32_at(at).unwrap_or(0), &bytes[at + 4..at + 8]);
        let start = at + 8;
        ensure!(
            start <= declared && length <= declared - start,
            "truncated .glb: the {} chunk at byte {at} declares {length} bytes but {} remain",
            String::from_utf8_lossy(kind).trim_end_matches('\0'),
            declared.saturating_sub(start)
        );
        chunks.push((kind, &bytes[start..start + length]));
        at = start + length;
    }
    match chunks.as_slice() {
        [(b"JSON", json), rest @ ..] => Ok((json, rest.first().filter(|(kind, _)| kind == b"BIN\0").map(|c| c.1))),
        [] => bail!("truncated .glb: it has no JSON chunk"),
        [(kind, _), ..] => bail!("malformed .glb: the first chunk is '{}', not JSON", String::from_utf8_lossy(kind)),
    }
}

/// A glTF object's name as messages put it after the object's index
/// (" 'name'"), or nothing for an unnamed one.
pub(crate) fn quoted_name(name: Option<&str>) -> String {
    name.map(|n| format!(" '{n}'")).unwrap_or_default()
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
