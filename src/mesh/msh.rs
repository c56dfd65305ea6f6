//! Reader for gmsh MSH 4.1 files, ASCII and binary (little-endian, data-size 8).
//!
//! Hand-written rather than built on a crate so that every failure can name the file, the
//! section, the line (ASCII) or byte offset (binary), and the gmsh element or node tag at
//! fault. Only what the solver needs is kept: physical names, entities with their physical
//! tags, nodes and elements; other sections ($Periodic, $NodeData, ...) are skipped.

use super::{Element, ElementKind, Mesh, PhysicalGroup};
use crate::error::{Error, Result};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// Reads and converts an MSH 4.1 file (see [`parse_msh`]).
pub fn read_msh(path: &Path) -> Result<Mesh> {
    let bytes = std::fs::read(path)
        .map_err(|e| Error::Mesh(format!("cannot read mesh file {}: {e}", path.display())))?;
    parse_msh(&bytes, &path.display().to_string())
}

/// Parses MSH 4.1 bytes into a [`Mesh`]. `source_name` only appears in error messages.
///
/// The cells are all elements of the highest dimension (2 or 3); lower-dimensional elements
/// are kept as `boundary` only if their entity carries a physical tag. Nodes not used by any
/// cell are dropped and the rest renumbered 0..n in increasing gmsh tag order.
pub fn parse_msh(bytes: &[u8], source_name: &str) -> Result<Mesh> {
    let raw = RawMsh::parse(bytes, source_name)?;
    raw.into_mesh(source_name)
}

/// One element as read, before node tags are resolved.
struct RawElement {
    kind: ElementKind,
    tag: u64,
    entity: i32,
    nodes: [u64; 8],
}

#[derive(Default)]
pub(super) struct RawMsh {
    /// (dim, physical tag) -> name.
    pub(super) names: BTreeMap<(usize, i32), String>,
    /// (dim, entity tag) -> physical tags.
    pub(super) entity_phys: HashMap<(usize, i32), Vec<i32>>,
    /// (gmsh tag, coordinates), in file order.
    nodes: Vec<(u64, [f64; 3])>,
    elements: Vec<RawElement>,
    seen_nodes: bool,
    seen_elements: bool,
}

/// Cursor over the file bytes that reads either ASCII tokens or binary values, so each
/// section parser is written once for both encodings.
pub(super) struct Cursor<'a> {
    pub(super) data: &'a [u8],
    pub(super) pos: usize,
    pub(super) binary: bool,
    pub(super) source: &'a str,
    /// Current section name, for error messages.
    pub(super) section: &'static str,
}

impl<'a> Cursor<'a> {
    pub(super) fn err(&self, msg: impl std::fmt::Display) -> Error {
        Error::Mesh(format!("{}: {msg} ({})", self.source, self.location()))
    }

    /// "line N in $Section" (ASCII, or text parts of binary files) or "byte N in $Section".
    fn location(&self) -> String {
        let pos = self.pos.min(self.data.len());
        if self.binary {
            format!("byte offset {pos} in {}", self.section)
        } else {
            let line = self.data[..pos].iter().filter(|&&b| b == b'\n').count() + 1;
            format!("line {line} in {}", self.section)
        }
    }

    fn at_end(&self) -> bool {
        self.pos >= self.data.len()
    }

    fn skip_ws(&mut self) {
        while self.pos < self.data.len() && self.data[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    /// Next whitespace-delimited ASCII token, or a "truncated" error.
    fn token(&mut self, what: &str) -> Result<&'a str> {
        self.skip_ws();
        let start = self.pos;
        while self.pos < self.data.len() && !self.data[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(self.err(format!("file truncated: expected {what}")));
        }
        std::str::from_utf8(&self.data[start..self.pos]).map_err(|_| {
            self.pos = start;
            self.err(format!("bad {what}: not ASCII text"))
        })
    }

    fn parse_token<T: std::str::FromStr>(&mut self, what: &str) -> Result<T> {
        let t = self.token(what)?;
        t.parse().map_err(|_| {
            let shown: String = t.chars().take(40).collect();
            self.err(format!("bad {what} \"{shown}\""))
        })
    }

    /// Rest of the current line (without the newline), trimmed.
    fn line(&mut self) -> &'a str {
        let start = self.pos;
        while self.pos < self.data.len() && self.data[self.pos] != b'\n' {
            self.pos += 1;
        }
        let end = self.pos;
        if self.pos < self.data.len() {
            self.pos += 1;
        }
        std::str::from_utf8(&self.data[start..end]).unwrap_or("").trim()
    }

    fn bytes<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        if self.pos + N > self.data.len() {
            return Err(self.err(format!("file truncated: expected {what}")));
        }
        let mut b = [0u8; N];
        b.copy_from_slice(&self.data[self.pos..self.pos + N]);
        self.pos += N;
        Ok(b)
    }

    /// A `size_t` (count or tag): 8 bytes in binary files.
    fn size(&mut self, what: &str) -> Result<u64> {
        if self.binary {
            Ok(u64::from_le_bytes(self.bytes::<8>(what)?))
        } else {
            self.parse_token(what)
        }
    }

    /// A count, also checked against the bytes left so corrupt counts cannot make us
    /// allocate absurd amounts of memory.
    fn count(&mut self, what: &str, min_bytes_each: usize) -> Result<usize> {
        let n = self.size(what)?;
        let left = self.data.len().saturating_sub(self.pos) as u64;
        if n.saturating_mul(min_bytes_each as u64) > left {
            return Err(self.err(format!("file truncated: {what} is {n} but too few bytes follow")));
        }
        Ok(n as usize)
    }

    /// An `int` (entity dimension or tag, element type, physical tag): 4 bytes in binary.
    fn int(&mut self, what: &str) -> Result<i32> {
        if self.binary {
            Ok(i32::from_le_bytes(self.bytes::<4>(what)?))
        } else {
            self.parse_token(what)
        }
    }

    fn double(&mut self, what: &str) -> Result<f64> {
        if self.binary {
            Ok(f64::from_le_bytes(self.bytes::<8>(what)?))
        } else {
            self.parse_token(what)
        }
    }

    /// An entity dimension: 0..=3.
    /// The header of `$Nodes` and `$Elements`: the number of blocks and of `item`s, then the
    /// minimum and maximum tag (unused). Returns (blocks, items).
    fn section_header(&mut self, item: &str) -> Result<(usize, usize)> {
        let blocks = self.count(&format!("number of {item} blocks"), 1)?;
        let items = self.count(&format!("number of {item}s"), 1)?;
        self.size(&format!("minimum {item} tag"))?;
        self.size(&format!("maximum {item} tag"))?;
        Ok((blocks, items))
    }

    fn dim(&mut self, what: &str) -> Result<usize> {
        let d = self.int(what)?;
        if !(0..=3).contains(&d) {
            return Err(self.err(format!("bad {what} {d} (must be 0..3)")));
        }
        Ok(d as usize)
    }

    /// Expects the `$EndName` line closing the current section.
    pub(super) fn end_section(&mut self, name: &str) -> Result<()> {
        self.skip_ws();
        let was_binary = self.binary;
        self.binary = false;
        let line = self.line();
        if line != format!("$End{name}") {
            self.binary = was_binary;
            let shown: String = line.chars().take(40).collect();
            return Err(self.err(format!(
                "expected $End{name}, found \"{shown}\" (counts in the section do not match its data)"
            )));
        }
        self.binary = was_binary;
        Ok(())
    }

    /// Skips to just after the line `$EndName` (for sections we do not read).
    fn skip_section(&mut self, name: &str) -> Result<()> {
        let pat = format!("$End{name}");
        let hay = &self.data[self.pos..];
        let found = hay.windows(pat.len()).position(|w| w == pat.as_bytes());
        match found {
            Some(i) => {
                self.pos += i + pat.len();
                Ok(())
            }
            None => {
                self.pos = self.data.len();
                Err(self.err(format!("file truncated: ${name} has no {pat}")))
            }
        }
    }
}

/// Human description of gmsh element types we refuse, for the error message.
fn unsupported_type(t: i32) -> (&'static str, bool) {
    // (description, is a higher-order Lagrange element)
    match t {
        6 => ("6-node prism", false),
        7 => ("5-node pyramid", false),
        8 => ("3-node second-order line", true),
        9 => ("6-node second-order triangle", true),
        10 => ("9-node second-order quadrangle", true),
        11 => ("10-node second-order tetrahedron", true),
        12 => ("27-node second-order hexahedron", true),
        13 => ("18-node second-order prism", true),
        14 => ("14-node second-order pyramid", true),
        16 => ("8-node second-order quadrangle", true),
        17 => ("20-node second-order hexahedron", true),
        18 => ("15-node second-order prism", true),
        19 => ("13-node second-order pyramid", true),
        20..=31 | 36..=66 | 71..=91 | 92..=98 => ("higher-order element", true),
        _ => ("unknown element type", false),
    }
}

/// The error for an element block of a type massfree does not read, naming the first element
/// (`first`: its tag, if the block has one) and the entity.
pub(super) fn unsupported_error(
    source: &str,
    gtype: i32,
    first: Option<u64>,
    dim: usize,
    entity: i32,
) -> Error {
    let at = match first {
        Some(t) => format!("element tag {t}"),
        None => "an empty block".to_string(),
    };
    let (what, high_order) = unsupported_type(gtype);
    let hint = if high_order {
        "; massfree needs first-order elements: set `Mesh.ElementOrder = 1;` \
         in the .geo (or mesh with `gmsh -order 1`)"
    } else {
        "; supported: 2-node lines, 3-node triangles, 4-node quadrangles, \
         4-node tetrahedra, 8-node hexahedra, points"
    };
    Error::Mesh(format!(
        "{source}: unsupported gmsh element type {gtype} ({what}) at {at} in entity \
         (dim {dim}, tag {entity}){hint}"
    ))
}

/// `$MeshFormat`: version 4.1, ASCII or binary (then little-endian), data size 8. Leaves
/// the cursor after `$EndMeshFormat`, in binary mode for a binary file.
pub(super) fn mesh_format(c: &mut Cursor) -> Result<()> {
    c.skip_ws();
    let first = c.line();
    if first != "$MeshFormat" {
        let shown: String = first.chars().take(40).collect();
        return Err(c.err(format!("not a gmsh MSH file: expected $MeshFormat, found \"{shown}\"")));
    }
    c.section = "$MeshFormat";
    let version = c.token("version")?.to_string();
    if version != "4.1" {
        return Err(
            c.err(format!("MSH 4.1 required, found {version}; mesh with `gmsh -format msh41`"))
        );
    }
    let file_type: i32 = c.parse_token("file type")?;
    let data_size: i32 = c.parse_token("data size")?;
    if data_size != 8 {
        return Err(c.err(format!("data size {data_size} not supported (need 8)")));
    }
    match file_type {
        0 => {}
        1 => {
            // Binary: the header line ends with '\n', then an int 1 to detect endianness.
            c.line();
            c.binary = true;
            let one = c.bytes::<4>("endianness marker")?;
            if i32::from_le_bytes(one) != 1 {
                return Err(c.err("big-endian binary MSH is not supported"));
            }
        }
        _ => return Err(c.err(format!("bad file type {file_type} (0 = ASCII, 1 = binary)"))),
    }
    c.end_section("MeshFormat")?;
    Ok(())
}

/// The name of the next section (its `$Name` header line read), or None at the end of the data.
pub(super) fn next_section<'a>(c: &mut Cursor<'a>) -> Result<Option<&'a str>> {
    c.skip_ws();
    if c.at_end() {
        return Ok(None);
    }
    let was_binary = c.binary;
    c.binary = false;
    c.section = "section header";
    let header = c.line();
    c.binary = was_binary;
    let Some(name) = header.strip_prefix('$') else {
        let shown: String = header.chars().take(40).collect();
        return Err(c.err(format!("expected a $Section header, found \"{shown}\"")));
    };
    Ok(Some(name))
}

impl RawMsh {
    fn parse(bytes: &[u8], source: &str) -> Result<RawMsh> {
        let mut c = Cursor { data: bytes, pos: 0, binary: false, source, section: "header" };
        let mut raw = RawMsh::default();
        mesh_format(&mut c)?;

        loop {
            let Some(name) = next_section(&mut c)? else {
                break;
            };
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
                "Nodes" => {
                    c.section = "$Nodes";
                    raw.read_nodes(&mut c)?;
                    c.end_section(name)?;
                }
                "Elements" => {
                    c.section = "$Elements";
                    raw.read_elements(&mut c)?;
                    c.end_section(name)?;
                }
                "PartitionedEntities" | "GhostElements" => {
                    return Err(c.err(
                        "partitioned MSH files are not supported; mesh without partitioning \
                         (massfree partitions the mesh itself)",
                    ));
                }
                _ => {
                    c.section = "unknown section";
                    c.skip_section(name)?;
                }
            }
        }
        if !raw.seen_nodes || !raw.seen_elements {
            return Err(Error::Mesh(format!(
                "{source}: file has no {} section (truncated file?)",
                if raw.seen_nodes { "$Elements" } else { "$Nodes" }
            )));
        }
        Ok(raw)
    }

    /// `$PhysicalNames` is text even in binary files: `dim tag "name"` per line.
    pub(super) fn physical_names(&mut self, c: &mut Cursor) -> Result<()> {
        let was_binary = c.binary;
        c.binary = false;
        let n: usize = c.parse_token("number of physical names")?;
        for _ in 0..n {
            let dim = c.dim("physical group dimension")?;
            let tag = c.int("physical tag")?;
            c.skip_ws();
            let rest = c.line();
            let name = rest
                .strip_prefix('"')
                .and_then(|r| r.strip_suffix('"'))
                .ok_or_else(|| c.err(format!("physical name not in double quotes: {rest}")))?;
            self.names.insert((dim, tag), name.to_string());
        }
        c.binary = was_binary;
        Ok(())
    }

    pub(super) fn entities(&mut self, c: &mut Cursor) -> Result<()> {
        let mut counts = [0usize; 4];
        for (d, n) in counts.iter_mut().enumerate() {
            *n = c.count(&format!("number of dimension-{d} entities"), 1)?;
        }
        for (dim, &n) in counts.iter().enumerate() {
            for _ in 0..n {
                let tag = c.int("entity tag")?;
                // Points have X Y Z, others a bounding box minX..maxZ.
                let n_coords = if dim == 0 { 3 } else { 6 };
                for _ in 0..n_coords {
                    c.double("entity coordinate")?;
                }
                let n_phys = c.count("number of physical tags", 1)?;
                let mut phys = Vec::with_capacity(n_phys);
                for _ in 0..n_phys {
                    phys.push(c.int("physical tag")?.abs());
                }
                if dim > 0 {
                    let n_bound = c.count("number of bounding entities", 1)?;
                    for _ in 0..n_bound {
                        c.int("bounding entity tag")?;
                    }
                }
                self.entity_phys.insert((dim, tag), phys);
            }
        }
        Ok(())
    }

    fn read_nodes(&mut self, c: &mut Cursor) -> Result<()> {
        self.seen_nodes = true;
        let (n_blocks, n_nodes) = c.section_header("node")?;
        self.nodes.reserve(n_nodes);
        for _ in 0..n_blocks {
            let dim = c.dim("entity dimension")?;
            let _entity = c.int("entity tag")?;
            let parametric = c.int("parametric flag")?;
            if parametric != 0 && parametric != 1 {
                return Err(c.err(format!("bad parametric flag {parametric}")));
            }
            // Parametric nodes carry `dim` extra coordinates (u, v, w) that we skip.
            let n_extra = if parametric == 1 { dim } else { 0 };
            let n = c.count("number of nodes in block", 1)?;
            let first = self.nodes.len();
            for _ in 0..n {
                let tag = c.size("node tag")?;
                self.nodes.push((tag, [0.0; 3]));
            }
            for i in 0..n {
                let mut x = [0.0; 3];
                for v in x.iter_mut() {
                    *v = c.double("node coordinate")?;
                }
                for _ in 0..n_extra {
                    c.double("parametric coordinate")?;
                }
                self.nodes[first + i].1 = x;
            }
        }
        if self.nodes.len() != n_nodes {
            return Err(c.err(format!(
                "header announces {n_nodes} nodes but the blocks hold {}",
                self.nodes.len()
            )));
        }
        Ok(())
    }

    fn read_elements(&mut self, c: &mut Cursor) -> Result<()> {
        self.seen_elements = true;
        let (n_blocks, n_elements) = c.section_header("element")?;
        self.elements.reserve(n_elements);
        for _ in 0..n_blocks {
            let dim = c.dim("entity dimension")?;
            let entity = c.int("entity tag")?;
            let gtype = c.int("element type")?;
            let n = c.count("number of elements in block", 1)?;
            let Some(kind) = ElementKind::from_gmsh(gtype) else {
                let first = if n > 0 { c.size("element tag").ok() } else { None };
                return Err(unsupported_error(c.source, gtype, first, dim, entity));
            };
            if kind.dim() != dim {
                return Err(c.err(format!(
                    "element block of type {gtype} ({}) declares entity dimension {dim}",
                    kind.name()
                )));
            }
            let nn = kind.n_nodes();
            for _ in 0..n {
                let tag = c.size("element tag")?;
                let mut nodes = [0u64; 8];
                for v in nodes.iter_mut().take(nn) {
                    *v = c.size("element node tag")?;
                }
                self.elements.push(RawElement { kind, tag, entity, nodes });
            }
        }
        if self.elements.len() != n_elements {
            return Err(c.err(format!(
                "header announces {n_elements} elements but the blocks hold {}",
                self.elements.len()
            )));
        }
        Ok(())
    }

    fn into_mesh(mut self, source: &str) -> Result<Mesh> {
        let dim = self.elements.iter().map(|e| e.kind.dim()).filter(|&d| d >= 2).max();
        let Some(dim) = dim else {
            return Err(Error::Mesh(format!(
                "{source}: no surface or volume elements (triangles, quadrangles, tetrahedra, \
                 hexahedra); mesh with `gmsh -2` or `-3` and make sure every body is in a \
                 Physical Surface/Volume"
            )));
        };

        // Nodes sorted by gmsh tag; lookups by binary search.
        self.nodes.sort_unstable_by_key(|n| n.0);
        if let Some(w) = self.nodes.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(Error::Mesh(format!("{source}: node tag {} appears twice", w[0].0)));
        }
        let lookup = |tag: u64, e: &RawElement| -> Result<usize> {
            self.nodes.binary_search_by_key(&tag, |n| n.0).map_err(|_| {
                Error::Mesh(format!(
                    "{source}: {} (gmsh element tag {}) references node tag {tag}, which is \
                     not in $Nodes",
                    e.kind.name(),
                    e.tag
                ))
            })
        };

        // Mark nodes used by cells, then renumber them in tag order.
        const UNUSED: usize = usize::MAX;
        let mut new_index = vec![UNUSED; self.nodes.len()];
        for e in self.elements.iter().filter(|e| e.kind.dim() == dim) {
            for &t in &e.nodes[..e.kind.n_nodes()] {
                new_index[lookup(t, e)?] = 0;
            }
        }
        let mut coords = Vec::new();
        let mut node_tags = Vec::new();
        for (i, &(tag, x)) in self.nodes.iter().enumerate() {
            if new_index[i] != UNUSED {
                new_index[i] = coords.len();
                coords.push(x);
                node_tags.push(tag);
            }
        }

        let has_physical = |d: usize, entity: i32| {
            self.entity_phys.get(&(d, entity)).is_some_and(|p| !p.is_empty())
        };
        let mut cells = Vec::new();
        let mut boundary = Vec::new();
        for e in &self.elements {
            let d = e.kind.dim();
            let is_cell = d == dim;
            if !is_cell && !has_physical(d, e.entity) {
                continue;
            }
            let mut nodes = [0usize; 8];
            for (k, &t) in e.nodes[..e.kind.n_nodes()].iter().enumerate() {
                let idx = new_index[lookup(t, e)?];
                if idx == UNUSED {
                    return Err(Error::Mesh(format!(
                        "{source}: boundary {} (gmsh element tag {}, entity {}) uses node tag \
                         {t}, which belongs to no {}D cell",
                        e.kind.name(),
                        e.tag,
                        e.entity,
                        dim
                    )));
                }
                nodes[k] = idx;
            }
            let el = Element::new(e.kind, &nodes[..e.kind.n_nodes()], e.tag, e.entity);
            if is_cell {
                cells.push(el);
            } else {
                boundary.push(el);
            }
        }

        let groups = self.groups();
        Ok(Mesh { dim, coords, node_tags, cells, boundary, groups })
    }

    /// Physical groups: names from $PhysicalNames, membership from $Entities.
    pub(super) fn groups(&self) -> Vec<PhysicalGroup> {
        let mut groups: BTreeMap<(usize, i32), Vec<i32>> =
            self.names.keys().map(|&k| (k, Vec::new())).collect();
        for (&(d, entity), phys) in &self.entity_phys {
            for &p in phys {
                groups.entry((d, p)).or_default().push(entity);
            }
        }
        groups
            .into_iter()
            .map(|((d, tag), mut entities)| {
                entities.sort_unstable();
                entities.dedup();
                let name = self.names.get(&(d, tag)).cloned().unwrap_or_else(|| tag.to_string());
                PhysicalGroup { name, dim: d, tag, entities }
            })
            .collect()
    }
}
