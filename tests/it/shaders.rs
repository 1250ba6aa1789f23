//! Every WGSL file in shaders/ is listed in `Shader::ALL`, and every listed
//! shader (with the pieces of shaders/include/ it uses prepended) parses and
//! validates with naga: a missing or broken shader cannot pass quietly. CPU
//! only.

use bake::gpu::Shader;

#[test]
fn every_shader_file_is_listed_once() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    on_disk.sort();
    let mut listed: Vec<String> = Shader::ALL.iter().map(|s| s.stem().to_string()).collect();
    listed.sort();
    assert_eq!(on_disk, listed, "shaders/ and Shader::ALL disagree");
}

#[test]
fn every_shader_validates() {
    for shader in Shader::ALL {
        let source = shader.source();
        let module = naga::front::wgsl::parse_str(&source)
            .unwrap_or_else(|e| panic!("{}: {}", shader.stem(), e.emit_to_string(&source)));
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
            .validate(&module)
            .unwrap_or_else(|e| panic!("{}: {}", shader.stem(), e.emit_to_string(&source)));
    }
}
