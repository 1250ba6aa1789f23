//! The committed fixtures are exactly what `cargo run --example
//! make_fixtures` writes: none is a blob that cannot be regenerated.

#[test]
fn committed_fixtures_match_their_generators() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    for (name, bytes) in bake::fixtures::files().unwrap() {
        let committed = std::fs::read(dir.join(&name)).unwrap_or_else(|e| panic!("fixtures/{name}: {e}"));
        assert!(
            committed == bytes,
            "fixtures/{name} differs from its generator: run `cargo run --release --example make_fixtures`"
        );
    }
}
