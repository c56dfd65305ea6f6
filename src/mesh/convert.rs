//! A large ASCII MSH file made binary once, so that the ranks can read it by byte ranges
//! (`share`): rank 0 runs `gmsh FILE -0 -bin -format msh41 -save_all` into a `.cache` folder
//! beside the file (or the system's temporary folder if that one cannot be written), the
//! others wait and read the result. gmsh keeps the tags, the entities, the physical groups and
//! the order of the blocks, and `-save_all` keeps the elements that belong to no physical group
//! (cells are all elements of the highest dimension). The cached file is reused while the
//! source keeps its path, size and modification time.

use crate::error::{Error, Result};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The binary version of the ASCII file `path` (collective; gmsh runs on rank 0).
pub fn to_binary(world: &SimpleCommunicator, path: &Path) -> Result<PathBuf> {
    let mut bytes = Vec::new();
    let mut code = 1i32;
    if world.rank() == 0 {
        match convert(path) {
            Ok(p) => bytes = p.display().to_string().into_bytes(),
            Err(e) => {
                code = 0;
                bytes = e.to_string().into_bytes();
            }
        }
    }
    let root = world.process_at_rank(0);
    root.broadcast_into(&mut code);
    let mut len = bytes.len() as u64;
    root.broadcast_into(&mut len);
    bytes.resize(len as usize, 0);
    root.broadcast_into(&mut bytes[..]);
    let text = String::from_utf8_lossy(&bytes).into_owned();
    if code == 1 {
        Ok(PathBuf::from(text))
    } else {
        Err(Error::Mesh(text.strip_prefix("mesh error: ").unwrap_or(&text).to_string()))
    }
}

/// Convert (or find the earlier conversion of) `path`.
fn convert(path: &Path) -> Result<PathBuf> {
    let meta = std::fs::metadata(path)
        .map_err(|e| Error::Mesh(format!("cannot read mesh file {}: {e}", path.display())))?;
    let full = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    let mtime = meta.modified().ok().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok());
    let mut key = Fnv::new();
    key.bytes(b"massfree binary msh v1");
    key.bytes(full.display().to_string().as_bytes());
    key.u64(meta.len());
    key.u64(mtime.map_or(0, |d| d.as_nanos() as u64));
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("mesh");
    let name = format!("{stem}-{:016x}.bin.msh", key.0);
    let beside = path.parent().unwrap_or(Path::new(".")).join(".cache");
    let dir = if std::fs::create_dir_all(&beside).is_ok() && writable(&beside) {
        beside
    } else {
        std::env::temp_dir()
    };
    let out = dir.join(&name);
    if out.is_file() {
        return Ok(out);
    }
    let tmp = dir.join(format!(".{name}.{}.tmp.msh", std::process::id()));
    let failed = |why: String| {
        let _ = std::fs::remove_file(&tmp);
        Error::Mesh(format!("{}: gmsh could not convert it to binary: {why}", path.display()))
    };
    let o = Command::new("gmsh")
        .arg(path)
        .args(["-0", "-bin", "-format", "msh41", "-save_all", "-v", "2", "-o"])
        .arg(&tmp)
        .output()
        .map_err(|e| failed(format!("cannot run gmsh: {e}")))?;
    let text = String::from_utf8_lossy(&o.stderr).to_string() + &String::from_utf8_lossy(&o.stdout);
    let error = text.lines().map(str::trim).find(|l| l.starts_with("Error"));
    if !o.status.success() || error.is_some() || !tmp.is_file() {
        return Err(failed(error.unwrap_or("no output file").to_string()));
    }
    std::fs::rename(&tmp, &out).map_err(|e| failed(format!("cannot move it into place: {e}")))?;
    Ok(out)
}

fn writable(dir: &Path) -> bool {
    let probe = dir.join(format!(".probe.{}", std::process::id()));
    let ok = std::fs::write(&probe, b"").is_ok();
    let _ = std::fs::remove_file(&probe);
    ok
}

/// 64-bit FNV-1a (stable across builds: the cache names stay valid).
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, b: &[u8]) {
        self.u64(b.len() as u64);
        for &x in b {
            self.0 = (self.0 ^ x as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn u64(&mut self, v: u64) {
        for x in v.to_le_bytes() {
            self.0 = (self.0 ^ x as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}
