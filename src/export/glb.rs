//! The binary glTF container (glTF 2.0 spec, section "GLB File Format").

/// A `.glb` file: 12-byte header, the JSON chunk padded with spaces, and the
/// BIN chunk (if any) padded with zeros, each to 4 bytes.
pub fn encode(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let pad = |n: usize| (4 - n % 4) % 4;
    let json_len = json.len() + pad(json.len());
    let bin_len = bin.len() + pad(bin.len());
    let total = 12 + 8 + json_len + if bin.is_empty() { 0 } else { 8 + bin_len };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_len as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(json);
    out.extend(std::iter::repeat_n(b' ', pad(json.len())));
    if !bin.is_empty() {
        out.extend_from_slice(&(bin_len as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
        out.extend(std::iter::repeat_n(0u8, pad(bin.len())));
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn chunks_are_aligned_and_length_is_total() {
        let glb = super::encode(b"{}", &[1, 2, 3]);
        assert_eq!(glb.len() % 4, 0);
        assert_eq!(u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize, glb.len());
        let parsed = gltf::binary::Glb::from_slice(&glb).unwrap();
        assert_eq!(parsed.json.trim_ascii(), b"{}");
        assert_eq!(&parsed.bin.unwrap()[..3], &[1, 2, 3]);
    }
}
