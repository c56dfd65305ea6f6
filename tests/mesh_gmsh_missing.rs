//! Its own test binary (own process) because it empties PATH.

use massfree::error::Error;
use massfree::mesh::gmsh::mesh_geo;
use std::path::Path;

#[test]
fn missing_gmsh_is_reported() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mesh-no-gmsh");
    std::fs::create_dir_all(dir.join("bin")).unwrap();
    std::env::set_var("PATH", dir.join("bin"));
    let geo = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/square_tri.geo");
    match mesh_geo(&geo, &[], 2, false, &dir.join("cache")) {
        Err(Error::Mesh(m)) => {
            assert_eq!(m, "gmsh not found: install the Debian package gmsh")
        }
        other => panic!("expected gmsh-not-found, got {other:?}"),
    }
}
