//! Where the node and element blocks of a binary MSH 4.1 file are, found by reading only the
//! file's small sections and the block headers: every block body is stepped over (its size
//! follows from its counts and element type), so a rank can then read just the byte ranges of
//! its share (`share`).
//!
//! Every rank walks the same headers and so finds the same layout, or the same error, without
//! talking to the others. The walk follows `msh::parse_msh` step by step, with the same checks
//! and messages (byte offsets included): a truncated or corrupt file fails here as it fails
//! there. The sections before the first `$Nodes`/`$Elements` (`$MeshFormat`, `$PhysicalNames`,
//! `$Entities`) are parsed by `msh`'s own code on a prefix of the file. (A `$PhysicalNames` or
//! `$Entities` section placed after the nodes, which gmsh never writes, is parsed the same way
//! but its error messages count bytes from the section's start.)

use super::msh::{mesh_format, next_section, unsupported_error, Cursor, RawMsh};
use super::{ElementKind, PhysicalGroup};
use crate::error::{Error, Result};
use std::collections::HashMap;
use std::fs::File;
use std::os::unix::fs::FileExt;

/// A block of nodes: `n` tags (8 bytes each) at `at`, then `n` rows of `3 + extra` doubles.
#[derive(Debug, Clone)]
pub struct NodeBlock {
    pub at: u64,
    pub n: usize,
    /// Parametric coordinates per node (skipped).
    pub extra: usize,
}

impl NodeBlock {
    pub fn coords_at(&self) -> u64 {
        self.at + 8 * self.n as u64
    }
    pub fn row_words(&self) -> usize {
        3 + self.extra
    }
}

/// A block of elements of one kind and entity: `n` rows (tag, node tags) of 8-byte words at `at`.
#[derive(Debug, Clone)]
pub struct ElementBlock {
    pub at: u64,
    pub n: usize,
    pub kind: ElementKind,
    pub entity: i32,
}

impl ElementBlock {
    pub fn row_words(&self) -> usize {
        1 + self.kind.n_nodes()
    }
}

/// The layout of a binary MSH 4.1 file (see the module doc).
#[derive(Debug, Clone)]
pub struct Layout {
    pub nodes: Vec<NodeBlock>,
    pub elements: Vec<ElementBlock>,
    /// (dim, entity tag) -> physical tags, from `$Entities`.
    pub entity_phys: HashMap<(usize, i32), Vec<i32>>,
    pub groups: Vec<PhysicalGroup>,
}

/// What the first sections say: a binary file's layout, or that the file is ASCII.
pub enum Scan {
    Binary(Layout),
    Ascii,
}

impl Layout {
    /// The mesh dimension: the highest dimension (2 or 3) among the elements there are.
    pub fn dim(&self, source: &str) -> Result<usize> {
        let dim = (self.elements.iter().filter(|b| b.n > 0))
            .map(|b| b.kind.dim())
            .filter(|&d| d >= 2)
            .max();
        dim.ok_or_else(|| {
            Error::Mesh(format!(
                "{source}: no surface or volume elements (triangles, quadrangles, tetrahedra, \
                 hexahedra); mesh with `gmsh -2` or `-3` and make sure every body is in a \
                 Physical Surface/Volume"
            ))
        })
    }

    /// Whether elements of dimension `d` in `entity` are kept as boundary elements.
    pub fn has_physical(&self, d: usize, entity: i32) -> bool {
        self.entity_phys.get(&(d, entity)).is_some_and(|p| !p.is_empty())
    }
}

/// Scan the file at `path` (named `source` in messages).
pub fn scan(file: &File, source: &str) -> Result<Scan> {
    let len = file
        .metadata()
        .map_err(|e| Error::Mesh(format!("cannot read mesh file {source}: {e}")))?
        .len();
    let mut raw = RawMsh::default();
    let Head::Next(stop) = head(file, len, source, &mut raw)? else {
        return Ok(Scan::Ascii);
    };
    let mut fc = FileCursor::new(file, len, source);
    let mut layout =
        Layout { nodes: vec![], elements: vec![], entity_phys: HashMap::new(), groups: vec![] };
    let (mut seen_nodes, mut seen_elements) = (false, false);
    let mut next = stop.map(|(name, pos)| {
        fc.pos = pos;
        fc.section = "section header";
        name
    });
    while let Some(name) = next {
        match name.as_str() {
            "Nodes" => {
                seen_nodes = true;
                fc.section = "$Nodes";
                node_blocks(&mut fc, &mut layout.nodes)?;
                fc.end_section(&name)?;
            }
            "Elements" => {
                seen_elements = true;
                fc.section = "$Elements";
                element_blocks(&mut fc, &mut layout.elements)?;
                fc.end_section(&name)?;
            }
            "PhysicalNames" | "Entities" => small_section(&mut fc, &name, &mut raw)?,
            "PartitionedEntities" | "GhostElements" => {
                return Err(fc.err(
                    "partitioned MSH files are not supported; mesh without partitioning \
                     (massfree partitions the mesh itself)",
                ));
            }
            _ => {
                fc.section = "unknown section";
                fc.skip_section(&name)?;
            }
        }
        next = fc.next_section()?;
    }
    if !seen_nodes || !seen_elements {
        return Err(Error::Mesh(format!(
            "{source}: file has no {} section (truncated file?)",
            if seen_nodes { "$Elements" } else { "$Nodes" }
        )));
    }
    layout.groups = raw.groups();
    layout.entity_phys = raw.entity_phys;
    Ok(Scan::Binary(layout))
}

/// Where the parse of the first sections stopped.
enum Head {
    /// The file is ASCII (nothing more was read).
    Ascii,
    /// The name of the next section and where its data starts; None at the end of the file.
    Next(Option<(String, u64)>),
}

/// The sections before the first `$Nodes` or `$Elements`, parsed by `msh` on a prefix of the
/// file that grows until the parse no longer depends on where the prefix ends.
fn head(file: &File, len: u64, source: &str, raw: &mut RawMsh) -> Result<Head> {
    let mut size = len.min(1 << 16);
    loop {
        let data = read_at(file, 0, size as usize, source)?;
        *raw = RawMsh::default();
        let whole = size == len;
        match head_of(&data, source, raw, whole) {
            Err(_) if !whole => size = len.min(size.saturating_mul(8)),
            r => return r,
        }
    }
}

/// [`head`] on the prefix `data`. On a prefix that is not the whole file (`!whole`), an error
/// may come from the cut: the caller retries with a longer one.
fn head_of(data: &[u8], source: &str, raw: &mut RawMsh, whole: bool) -> Result<Head> {
    let mut c = Cursor { data, pos: 0, binary: false, source, section: "header" };
    mesh_format(&mut c)?;
    if !c.binary {
        return Ok(Head::Ascii);
    }
    let cut = || Error::Mesh(format!("{source}: prefix cut"));
    loop {
        let Some(name) = next_section(&mut c)? else {
            return if whole { Ok(Head::Next(None)) } else { Err(cut()) };
        };
        // The header line must end inside the prefix.
        if !whole && data[c.pos - 1] != b'\n' {
            return Err(cut());
        }
        match name {
            "PhysicalNames" => {
                c.section = "$PhysicalNames";
                raw.physical_names(&mut c)?;
                c.end_section(name)?;
            }
            "Entities" => {
                c.section = "$Entities";
                raw.entities(&mut c)?;
                c.end_section(name)?;
            }
            // Nodes, elements, partitioned files, unknown sections: the file walk goes on.
            _ => return Ok(Head::Next(Some((name.to_string(), c.pos as u64)))),
        }
        if !whole && c.pos >= data.len() {
            return Err(cut());
        }
    }
}

/// A `$PhysicalNames` or `$Entities` section after the nodes: its bytes up to `$EndName`,
/// parsed by `msh`.
fn small_section(fc: &mut FileCursor, name: &str, raw: &mut RawMsh) -> Result<()> {
    let start = fc.pos;
    fc.section = if name == "Entities" { "$Entities" } else { "$PhysicalNames" };
    fc.skip_section(name)?;
    let data = read_at(fc.file, start, (fc.pos - start) as usize, fc.source)?;
    let section = fc.section;
    let mut c = Cursor { data: &data, pos: 0, binary: true, source: fc.source, section };
    if name == "Entities" {
        raw.entities(&mut c)?;
    } else {
        raw.physical_names(&mut c)?;
    }
    c.end_section(name)?;
    fc.pos = start + c.pos as u64;
    Ok(())
}

/// The blocks of one `$Nodes` section (appended: a file may have several).
fn node_blocks(fc: &mut FileCursor, blocks: &mut Vec<NodeBlock>) -> Result<()> {
    let (n_blocks, n_nodes) = fc.section_header("node")?;
    for _ in 0..n_blocks {
        let dim = fc.dim("entity dimension")?;
        let _entity = fc.int("entity tag")?;
        let parametric = fc.int("parametric flag")?;
        if parametric != 0 && parametric != 1 {
            return Err(fc.err(format!("bad parametric flag {parametric}")));
        }
        let extra = if parametric == 1 { dim } else { 0 };
        let n = fc.count("number of nodes in block", 1)?;
        let b = NodeBlock { at: fc.pos, n, extra };
        let words = n as u64 * (1 + b.row_words() as u64);
        fc.step_over(words, |k| {
            if k < n as u64 {
                "node tag"
            } else if (k - n as u64) % (b.row_words() as u64) < 3 {
                "node coordinate"
            } else {
                "parametric coordinate"
            }
        })?;
        blocks.push(b);
    }
    let held: usize = blocks.iter().map(|b| b.n).sum();
    if held != n_nodes {
        return Err(fc.err(format!("header announces {n_nodes} nodes but the blocks hold {held}")));
    }
    Ok(())
}

/// The blocks of one `$Elements` section (appended).
fn element_blocks(fc: &mut FileCursor, blocks: &mut Vec<ElementBlock>) -> Result<()> {
    let (n_blocks, n_elements) = fc.section_header("element")?;
    for _ in 0..n_blocks {
        let dim = fc.dim("entity dimension")?;
        let entity = fc.int("entity tag")?;
        let gtype = fc.int("element type")?;
        let n = fc.count("number of elements in block", 1)?;
        let Some(kind) = ElementKind::from_gmsh(gtype) else {
            let first = if n > 0 { fc.size("element tag").ok() } else { None };
            return Err(unsupported_error(fc.source, gtype, first, dim, entity));
        };
        if kind.dim() != dim {
            return Err(fc.err(format!(
                "element block of type {gtype} ({}) declares entity dimension {dim}",
                kind.name()
            )));
        }
        let b = ElementBlock { at: fc.pos, n, kind, entity };
        let row = b.row_words() as u64;
        fc.step_over(n as u64 * row, |k| {
            if k % row == 0 {
                "element tag"
            } else {
                "element node tag"
            }
        })?;
        blocks.push(b);
    }
    let held: usize = blocks.iter().map(|b| b.n).sum();
    if held != n_elements {
        return Err(
            fc.err(format!("header announces {n_elements} elements but the blocks hold {held}"))
        );
    }
    Ok(())
}

/// `len` bytes of the file from `at` (the caller knows they are there).
pub fn read_at(file: &File, at: u64, len: usize, source: &str) -> Result<Vec<u8>> {
    let mut buf = vec![0u8; len];
    file.read_exact_at(&mut buf, at)
        .map_err(|e| Error::Mesh(format!("cannot read mesh file {source}: {e}")))?;
    Ok(buf)
}

/// The binary part of `msh`'s cursor over a file instead of a byte slice: the same reads, the
/// same checks, the same messages, at absolute byte offsets; a small window is cached.
struct FileCursor<'a> {
    file: &'a File,
    len: u64,
    pos: u64,
    source: &'a str,
    section: &'static str,
    window: Vec<u8>,
    window_at: u64,
}

const WINDOW: usize = 1 << 16;

impl<'a> FileCursor<'a> {
    fn new(file: &'a File, len: u64, source: &'a str) -> FileCursor<'a> {
        FileCursor { file, len, pos: 0, source, section: "header", window: vec![], window_at: 0 }
    }

    fn err(&self, msg: impl std::fmt::Display) -> Error {
        let pos = self.pos.min(self.len);
        Error::Mesh(format!("{}: {msg} (byte offset {pos} in {})", self.source, self.section))
    }

    /// The byte at `p` (< len), through the window.
    fn byte(&mut self, p: u64) -> Result<u8> {
        let inside = p >= self.window_at && p < self.window_at + self.window.len() as u64;
        if !inside {
            let n = (self.len - p).min(WINDOW as u64) as usize;
            self.window = read_at(self.file, p, n, self.source)?;
            self.window_at = p;
        }
        Ok(self.window[(p - self.window_at) as usize])
    }

    fn bytes<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        if self.pos + N as u64 > self.len {
            return Err(self.err(format!("file truncated: expected {what}")));
        }
        let mut b = [0u8; N];
        for (k, x) in b.iter_mut().enumerate() {
            *x = self.byte(self.pos + k as u64)?;
        }
        self.pos += N as u64;
        Ok(b)
    }

    fn size(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.bytes::<8>(what)?))
    }

    fn int(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.bytes::<4>(what)?))
    }

    fn count(&mut self, what: &str, min_bytes_each: usize) -> Result<usize> {
        let n = self.size(what)?;
        let left = self.len.saturating_sub(self.pos);
        if n.saturating_mul(min_bytes_each as u64) > left {
            return Err(self.err(format!("file truncated: {what} is {n} but too few bytes follow")));
        }
        Ok(n as usize)
    }

    fn dim(&mut self, what: &str) -> Result<usize> {
        let d = self.int(what)?;
        if !(0..=3).contains(&d) {
            return Err(self.err(format!("bad {what} {d} (must be 0..3)")));
        }
        Ok(d as usize)
    }

    fn section_header(&mut self, item: &str) -> Result<(usize, usize)> {
        let blocks = self.count(&format!("number of {item} blocks"), 1)?;
        let items = self.count(&format!("number of {item}s"), 1)?;
        self.size(&format!("minimum {item} tag"))?;
        self.size(&format!("maximum {item} tag"))?;
        Ok((blocks, items))
    }

    /// Step over `words` 8-byte values; if the file ends first, fail where reading them one by
    /// one would (`what(k)` names value `k`).
    fn step_over(&mut self, words: u64, what: impl Fn(u64) -> &'static str) -> Result<()> {
        let fit = self.len.saturating_sub(self.pos) / 8;
        if fit < words {
            self.pos += 8 * fit;
            return Err(self.err(format!("file truncated: expected {}", what(fit))));
        }
        self.pos += 8 * words;
        Ok(())
    }

    fn skip_ws(&mut self) -> Result<()> {
        while self.pos < self.len && self.byte(self.pos)?.is_ascii_whitespace() {
            self.pos += 1;
        }
        Ok(())
    }

    /// The rest of the line, trimmed (at most its first 4 KiB are kept: enough to compare
    /// with a section name and to show 40 characters).
    fn line(&mut self) -> Result<String> {
        let mut text = Vec::new();
        while self.pos < self.len {
            let b = self.byte(self.pos)?;
            self.pos += 1;
            if b == b'\n' {
                break;
            }
            if text.len() < 4096 {
                text.push(b);
            }
        }
        Ok(std::str::from_utf8(&text).unwrap_or("").trim().to_string())
    }

    fn end_section(&mut self, name: &str) -> Result<()> {
        self.skip_ws()?;
        let line = self.line()?;
        if line != format!("$End{name}") {
            let shown: String = line.chars().take(40).collect();
            return Err(self.err(format!(
                "expected $End{name}, found \"{shown}\" (counts in the section do not match its data)"
            )));
        }
        Ok(())
    }

    fn next_section(&mut self) -> Result<Option<String>> {
        self.skip_ws()?;
        if self.pos >= self.len {
            return Ok(None);
        }
        self.section = "section header";
        let header = self.line()?;
        let Some(name) = header.strip_prefix('$') else {
            let shown: String = header.chars().take(40).collect();
            return Err(self.err(format!("expected a $Section header, found \"{shown}\"")));
        };
        Ok(Some(name.to_string()))
    }

    /// Past the first `$EndName` (a streaming search).
    fn skip_section(&mut self, name: &str) -> Result<()> {
        let pat = format!("$End{name}").into_bytes();
        let mut matched = 0usize;
        while self.pos < self.len {
            let b = self.byte(self.pos)?;
            self.pos += 1;
            matched = if b == pat[matched] {
                matched + 1
            } else if b == pat[0] {
                1
            } else {
                0
            };
            if matched == pat.len() {
                return Ok(());
            }
        }
        Err(self.err(format!("file truncated: ${name} has no $End{name}")))
    }
}
