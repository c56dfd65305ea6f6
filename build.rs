//! Generates the PETSc FFI with bindgen from Debian's PETSc 3.18 and links it.
//!
//! The solver assumes 32-bit `PetscInt` and real double `PetscScalar`; any other PETSc build
//! fails here (and again at compile time in `src/petsc/ffi.rs`), not at run time.

use std::env;
use std::path::{Path, PathBuf};
use std::process::Command;

const FALLBACK_DIR: &str = "/usr/lib/petscdir/petsc3.18/x86_64-linux-gnu-real";
const WRAPPER: &str = "petsc_wrapper.h";

/// Runs `cmd args` and returns its stdout split on whitespace, or `None` if it failed.
fn tokens(cmd: &str, args: &[&str]) -> Option<Vec<String>> {
    let out = Command::new(cmd).args(args).output().ok()?;
    if !out.status.success() {
        return None;
    }
    let s = String::from_utf8(out.stdout).ok()?;
    Some(s.split_whitespace().map(str::to_owned).collect())
}

/// PETSc include dirs, library dirs and library names: pkg-config first (`PETSc` or `petsc`,
/// as PETSc installs it; Debian's names the library `petsc_real`), the Debian path otherwise.
fn petsc_dirs() -> (Vec<PathBuf>, Vec<PathBuf>, Vec<String>) {
    let mut inc = Vec::new();
    let mut lib = Vec::new();
    let mut names = Vec::new();
    let toks = tokens("pkg-config", &["--cflags", "--libs", "PETSc"])
        .or_else(|| tokens("pkg-config", &["--cflags", "--libs", "petsc"]));
    for t in toks.unwrap_or_default() {
        if let Some(p) = t.strip_prefix("-I") {
            inc.push(PathBuf::from(p));
        } else if let Some(p) = t.strip_prefix("-L") {
            lib.push(PathBuf::from(p));
        } else if let Some(n) = t.strip_prefix("-l") {
            names.push(n.to_string());
        }
    }
    if inc.is_empty() {
        inc.push(Path::new(FALLBACK_DIR).join("include"));
    }
    if lib.is_empty() {
        lib.push(Path::new(FALLBACK_DIR).join("lib"));
    }
    if names.is_empty() {
        names.push("petsc_real".to_string());
    }
    (inc, lib, names)
}

/// MPI include dirs: pkg-config (`ompi-c` for Open MPI, `mpich`) first, then the compiler
/// wrapper (`mpicc --showme:incdirs` for Open MPI, `mpicc -show` for MPICH and its kin).
fn mpi_include_dirs() -> Vec<PathBuf> {
    let includes = |toks: Vec<String>| -> Vec<PathBuf> {
        toks.iter().filter_map(|t| t.strip_prefix("-I")).map(PathBuf::from).collect()
    };
    for pc in ["ompi-c", "mpich"] {
        let dirs = includes(tokens("pkg-config", &["--cflags", pc]).unwrap_or_default());
        if !dirs.is_empty() {
            return dirs;
        }
    }
    if let Some(dirs) = tokens("mpicc", &["--showme:incdirs"]) {
        return dirs.into_iter().map(PathBuf::from).collect();
    }
    includes(tokens("mpicc", &["-show"]).unwrap_or_default())
}

/// Refuses PETSc builds whose scalar/index types the solver was not written for.
fn check_petscconf(inc: &[PathBuf]) {
    let conf =
        inc.iter().map(|d| d.join("petscconf.h")).find(|p| p.exists()).unwrap_or_else(|| {
            panic!("petscdev build: petscconf.h not found in PETSc include dirs {inc:?}")
        });
    println!("cargo:rerun-if-changed={}", conf.display());
    let text = std::fs::read_to_string(&conf)
        .unwrap_or_else(|e| panic!("petscdev build: cannot read {}: {e}", conf.display()));
    let defined = |name: &str| {
        text.lines().any(|l| {
            let mut w = l.split_whitespace();
            w.next() == Some("#define") && w.next() == Some(name)
        })
    };
    let mut problems = Vec::new();
    if defined("PETSC_USE_64BIT_INDICES") {
        problems.push("PETSC_USE_64BIT_INDICES is defined (PetscInt must be 32-bit)");
    }
    if !defined("PETSC_USE_REAL_DOUBLE") {
        problems.push("PETSC_USE_REAL_DOUBLE is not defined (PetscReal must be double)");
    }
    if defined("PETSC_USE_COMPLEX") {
        problems.push("PETSC_USE_COMPLEX is defined (PetscScalar must be real)");
    }
    if !problems.is_empty() {
        panic!(
            "petscdev build: unsupported PETSc configuration in {}:\n  {}\n\
             Install a real, double precision, 32-bit index PETSc (Debian: petsc-dev).",
            conf.display(),
            problems.join("\n  ")
        );
    }
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed={WRAPPER}");
    println!("cargo:rerun-if-env-changed=PKG_CONFIG_PATH");

    let (petsc_inc, petsc_lib, petsc_names) = petsc_dirs();
    check_petscconf(&petsc_inc);
    let mpi_inc = mpi_include_dirs();

    for d in &petsc_lib {
        println!("cargo:rustc-link-search=native={}", d.display());
        // Debian's libpetsc_real is not in the default runtime search path on every setup.
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", d.display());
    }
    for name in &petsc_names {
        println!("cargo:rustc-link-lib={name}");
    }
    println!("cargo:rustc-link-lib=mpi");

    let mut builder = bindgen::Builder::default()
        .header(WRAPPER)
        .generate_comments(false)
        .layout_tests(false)
        .derive_default(true)
        .allowlist_function("^(Petsc|Mat|Vec|KSP|PC|IS)[A-Za-z0-9_]*")
        .allowlist_function("^MPI_(Comm_rank|Comm_size|Wtime|Initialized|Finalized)$")
        .allowlist_type("^(Petsc|Mat|Vec|KSP|PC|IS|InsertMode|ScatterMode|NormType)[A-Za-z0-9_]*")
        .allowlist_var("^PETSC_COMM_WORLD$")
        .allowlist_var("^(MATAIJ|MATBAIJ|VECSTANDARD)$")
        .allowlist_var("^(KSPConvergedReasons|PETSC_DEFAULT|PETSC_DECIDE|PETSC_DETERMINE)$")
        // Variadic and callback-heavy corners we never call; keeps the bindings smaller.
        .blocklist_function(".*(Fortran|_Private|Python).*")
        .parse_callbacks(Box::new(bindgen::CargoCallbacks::new()));
    for d in petsc_inc.iter().chain(mpi_inc.iter()) {
        builder = builder.clang_arg(format!("-I{}", d.display()));
    }
    let bindings = builder.generate().expect("petscdev build: bindgen failed on petsc_wrapper.h");
    let out =
        PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR not set")).join("petsc_bindings.rs");
    bindings
        .write_to_file(&out)
        .unwrap_or_else(|e| panic!("petscdev build: cannot write {}: {e}", out.display()));
}
