//! Meshing `.geo` sources with the `gmsh` command, with a content-addressed cache so that
//! re-running a scene (or many ranks asking for the same mesh) does not re-mesh.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The parameters a `.geo` text declares with `DefineConstant[ NAME = {...}, ... ];` (or
/// `NAME = value`): the only ones `-setnumber` can set.
pub fn declared_parameters(geo: &str) -> Vec<String> {
    // Without comments: `//` to the end of a line, `/* ... */`.
    let mut text = String::with_capacity(geo.len());
    let mut rest = geo;
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("//") {
            rest = r.find('\n').map_or("", |i| &r[i..]);
        } else if let Some(r) = rest.strip_prefix("/*") {
            rest = r.find("*/").map_or("", |i| &r[i + 2..]);
        } else {
            let c = rest.chars().next().expect("not empty");
            text.push(c);
            rest = &rest[c.len_utf8()..];
        }
    }
    let mut names = Vec::new();
    let mut at = 0;
    while let Some(i) = text[at..].find("DefineConstant") {
        let start = at + i + "DefineConstant".len();
        let Some(open) = text[start..].find('[').map(|j| start + j + 1) else { break };
        // The block's entries: split at the commas outside braces, up to the closing `]`.
        let (mut depth, mut entry, mut end) = (0usize, String::new(), text.len());
        for (k, c) in text[open..].char_indices() {
            match c {
                '{' | '(' => depth += 1,
                '}' | ')' => depth = depth.saturating_sub(1),
                ']' if depth == 0 => {
                    end = open + k;
                    break;
                }
                _ => {}
            }
            if c == ',' && depth == 0 {
                names.extend(entry_name(&entry));
                entry.clear();
            } else {
                entry.push(c);
            }
        }
        names.extend(entry_name(&entry));
        at = end.min(text.len());
        if at <= start {
            break;
        }
    }
    names.sort();
    names.dedup();
    names
}

/// `NAME` of a `NAME = ...` entry.
fn entry_name(entry: &str) -> Option<String> {
    let (name, _) = entry.split_once('=')?;
    let name = name.trim();
    let ok = name.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    ok.then(|| name.to_string())
}

/// Meshes `geo` with gmsh in dimension `dim` and returns the path of the MSH 4.1 file.
///
/// Runs `gmsh <geo> -<dim> -format msh41 [-bin] -setnumber NAME VALUE ... -o <out> -v 2`.
/// `-setnumber` overrides parameters the .geo declares with
/// `DefineConstant[ h = {0.25, Name "h"} ];` (a plain `h = 0.25;` would ignore it).
/// The output is `cache_dir/<stem>-<hash>.msh`, the hash covering the .geo content, the
/// parameters, `dim`, `binary` and the gmsh version; an existing file is reused as is.
/// gmsh writes to a temporary name that is renamed into place, so concurrent callers never
/// see a half-written mesh. Files the .geo `Include`s are not part of the hash.
pub fn mesh_geo(
    geo: &Path,
    params: &[(String, f64)],
    dim: usize,
    binary: bool,
    cache_dir: &Path,
) -> Result<PathBuf> {
    if !(1..=3).contains(&dim) {
        return Err(Error::Mesh(format!(
            "meshing {}: dimension {dim} is not 1, 2 or 3",
            geo.display()
        )));
    }
    for (name, value) in params {
        let ok_name = name.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !ok_name {
            return Err(Error::Mesh(format!(
                "meshing {}: bad gmsh parameter name \"{name}\"",
                geo.display()
            )));
        }
        if !value.is_finite() {
            return Err(Error::Mesh(format!(
                "meshing {}: parameter {name} = {value} is not finite",
                geo.display()
            )));
        }
    }
    let content = std::fs::read(geo)
        .map_err(|e| Error::Mesh(format!("cannot read geo file {}: {e}", geo.display())))?;
    let version = gmsh_version()?;

    let mut h = Fnv::new();
    h.bytes(b"massfree mesh cache v1");
    h.bytes(&content);
    h.bytes(version.as_bytes());
    h.u64(dim as u64);
    h.u64(binary as u64);
    h.u64(params.len() as u64);
    for (name, value) in params {
        h.bytes(name.as_bytes());
        h.u64(value.to_bits());
    }
    let stem = geo.file_stem().and_then(|s| s.to_str()).unwrap_or("mesh");
    let out = cache_dir.join(format!("{stem}-{:016x}.msh", h.0));
    if out.is_file() {
        return Ok(out);
    }

    std::fs::create_dir_all(cache_dir).map_err(|e| {
        Error::Mesh(format!("cannot create mesh cache folder {}: {e}", cache_dir.display()))
    })?;
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let tmp = cache_dir.join(format!(
        ".{stem}-{:016x}.{}.{}.tmp.msh",
        h.0,
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));

    let mut cmd = Command::new("gmsh");
    cmd.arg(geo).arg(format!("-{dim}")).args(["-format", "msh41"]);
    if binary {
        cmd.arg("-bin");
    }
    for (name, value) in params {
        cmd.arg("-setnumber").arg(name).arg(value.to_string());
    }
    cmd.arg("-o").arg(&tmp).args(["-v", "2"]);
    let result = run_interruptible(&mut cmd);
    let failed = |why: String| {
        let _ = std::fs::remove_file(&tmp);
        Err(Error::Mesh(format!("gmsh failed on {}: {why}", geo.display())))
    };
    if crate::phase::signalled() {
        let _ = std::fs::remove_file(&tmp);
        return Err(crate::phase::interrupted());
    }
    let output = match result {
        Ok(o) => o,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(not_found()),
        Err(e) => return failed(format!("cannot run gmsh: {e}")),
    };
    // gmsh can exit 0 after reporting errors, and writes an output file even on failure.
    if let Some(why) = failure(&output) {
        return failed(why);
    }
    if !tmp.is_file() {
        return failed("gmsh wrote no output file".to_string());
    }
    std::fs::rename(&tmp, &out).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::Mesh(format!("cannot move the mesh into place at {}: {e}", out.display()))
    })?;
    Ok(out)
}

/// Run gmsh to its end, or until SIGINT/SIGTERM reaches this process: then gmsh is killed at
/// once (meshing a large model can take minutes, and a stopped run must end quickly).
fn run_interruptible(cmd: &mut Command) -> std::io::Result<Output> {
    use std::io::Read;
    let mut child = cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn()?;
    let drain = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            if let Some(mut p) = pipe {
                let _ = p.read_to_end(&mut buf);
            }
            buf
        })
    };
    let out = drain(child.stdout.take().map(|p| Box::new(p) as Box<dyn Read + Send>));
    let err = drain(child.stderr.take().map(|p| Box::new(p) as Box<dyn Read + Send>));
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        if crate::phase::signalled() {
            let _ = child.kill();
            break child.wait()?;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    Ok(Output {
        status,
        stdout: out.join().unwrap_or_default(),
        stderr: err.join().unwrap_or_default(),
    })
}

fn not_found() -> Error {
    Error::Mesh("gmsh not found: install the Debian package gmsh".to_string())
}

/// `gmsh --version` (printed on stderr by gmsh 4.8), part of the cache key.
fn gmsh_version() -> Result<String> {
    let o = Command::new("gmsh").arg("--version").output().map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            not_found()
        } else {
            Error::Mesh(format!("cannot run gmsh --version: {e}"))
        }
    })?;
    let text =
        format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    Ok(text.trim().to_string())
}

/// Why a gmsh run failed, if it did: its last "Error" line, else its last line.
fn failure(o: &Output) -> Option<String> {
    let text =
        format!("{}\n{}", String::from_utf8_lossy(&o.stderr), String::from_utf8_lossy(&o.stdout));
    let lines: Vec<&str> = text.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
    let error_line = lines.iter().rev().find(|l| l.starts_with("Error")).copied();
    if o.status.success() && error_line.is_none() {
        return None;
    }
    let status = match o.status.code() {
        Some(c) => format!("exit status {c}"),
        None => "killed by a signal (crashed)".to_string(),
    };
    Some(match error_line.or(lines.last().copied()) {
        Some(l) => format!("{l} ({status})"),
        None => status,
    })
}

/// 64-bit FNV-1a: stable across Rust versions (unlike `DefaultHasher`), so the cache
/// names stay valid between builds.
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn byte(&mut self, b: u8) {
        self.0 = (self.0 ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
    }
    /// Length-prefixed, so that consecutive fields cannot run into each other.
    fn bytes(&mut self, b: &[u8]) {
        self.u64(b.len() as u64);
        for &x in b {
            self.byte(x);
        }
    }
    fn u64(&mut self, v: u64) {
        for x in v.to_le_bytes() {
            self.byte(x);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::declared_parameters;

    #[test]
    fn the_declared_parameters_are_read_from_define_constant_blocks() {
        let geo = r#"
// h = 1 in a comment is no parameter
DefineConstant[ h = {0.25, Name "h"} ];
/* DefineConstant[ ghost = {1} ]; */
DefineConstant[
  W = {1, Name "W"},
  ny = {0, Name "ny", Min 0, Max 10},   // 0: automatic
  ar = 2
];
x = 3;
"#;
        assert_eq!(declared_parameters(geo), ["W", "ar", "h", "ny"]);
        assert!(declared_parameters("x = 1;").is_empty());
    }

    #[test]
    fn every_shipped_mesh_declares_its_parameters() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes");
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let path = e.path();
            if path.extension().is_some_and(|x| x == "geo") {
                let text = std::fs::read_to_string(&path).unwrap();
                if text.contains("DefineConstant") {
                    assert!(!declared_parameters(&text).is_empty(), "{}", path.display());
                }
            }
        }
    }
}
