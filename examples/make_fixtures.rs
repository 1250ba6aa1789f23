//! Writes every file in `fixtures/` from the generators in
//! `bake::fixtures` and `bake::environment`, so no fixture is a blob that
//! cannot be regenerated. `tests/fixtures.rs` checks the committed files
//! are exactly what this writes.
//!
//!     cargo run --release --example make_fixtures

fn main() -> anyhow::Result<()> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    std::fs::create_dir_all(&dir)?;
    for (name, bytes) in bake::fixtures::files()? {
        std::fs::write(dir.join(&name), bytes)?;
        println!("wrote fixtures/{name}");
    }
    Ok(())
}
