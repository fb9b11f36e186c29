//! `include/orbitflex.h` is what cbindgen 0.29.4 makes of `capi/src`: this test fails when
//! the checked-in header is out of date. `ORBITFLEX_BLESS=1` rewrites it instead.

#[test]
fn the_header_is_up_to_date() {
    let dir = env!("CARGO_MANIFEST_DIR");
    let config = cbindgen::Config::from_file(format!("{dir}/cbindgen.toml")).expect("config");
    let mut fresh = Vec::new();
    cbindgen::Builder::new()
        .with_crate(dir)
        .with_config(config)
        .generate()
        .expect("cbindgen parses capi/src")
        .write(&mut fresh);
    let path = format!("{dir}/../include/orbitflex.h");
    if std::env::var_os("ORBITFLEX_BLESS").is_some() {
        std::fs::write(&path, &fresh).expect("write the header");
        return;
    }
    let checked_in = std::fs::read(&path).unwrap_or_default();
    assert!(
        fresh == checked_in,
        "{path} is out of date with capi/src: regenerate it with\n  ORBITFLEX_BLESS=1 cargo test \
         --release -p orbitflex-capi --test header\n(or cbindgen 0.29.4, see capi/cbindgen.toml) \
         and commit it"
    );
}
