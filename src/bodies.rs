//! The bodies of a scene on its mesh (`[[body]]`, see the scene module): which cells each body
//! holds, hence the material and the mass treatment of every cell, and along which contact
//! groups the mass-free layer runs.
//!
//! Region 0 is the cells outside every body (`[material]`, `mass.kind`); region `i + 1` is
//! `body[i]`. Everything is resolved once, before assembly, from the whole mesh every rank
//! holds, in a fixed order: every rank gets the same regions and layer groups whatever the
//! partition, and nothing here runs per time step.
//!
//! The layer rule (docs/method.md, the mass-free layer per body): a contact group gets the mass-free layer when
//! the cells it touches (the cells with a node on it: its layer cells) have a modified mass. So
//! those cells must all have the same mass kind, one run builds one variant, and a body whose
//! own `mass` is modified must carry a contact group. A body that only inherits a modified
//! `mass.kind` and carries no contact group keeps the consistent mass (`M_H` with an empty
//! layer is `M`).

use std::collections::HashMap;

use crate::error::{Error, Result};
use crate::fem::Material;
use crate::mesh::topology::boundary_group;
use crate::mesh::Mesh;
use crate::partition::surface::Surface;
use crate::partition::Partition;
use crate::scene::{Formulation, MassKind, MaterialSpec, Scene};
use crate::time::Regime;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// Cells with one material and one mass treatment: the cells outside every body, or a body.
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// `body[i] "lower"`, or `the cells outside every [[body]]` (for messages).
    pub name: String,
    /// The body's group (None for region 0).
    pub group: Option<String>,
    pub spec: MaterialSpec,
    pub material: Material,
    pub mass: MassKind,
    /// The mass kind was given for this region (`body[i].mass`), not inherited.
    pub mass_given: bool,
    pub n_cells: usize,
}

/// The regions of a mesh and the mass-free layer's groups.
#[derive(Debug, Clone, PartialEq)]
pub struct Bodies {
    /// Region 0: the cells outside every body; region `i + 1`: `body[i]`.
    pub regions: Vec<Region>,
    /// The region of each cell; empty when the scene has no `[[body]]` (all in region 0).
    cell_region: Vec<u16>,
    /// Sorted nodes of the cells of `body[i]`.
    body_nodes: Vec<Vec<usize>>,
    /// The layer to build: its kind (modified0 or modified1) and the groups it runs along.
    pub layer: Option<(MassKind, Vec<String>)>,
    /// Regions whose (modified) mass gets no layer: their cells get the consistent mass.
    no_layer: Vec<bool>,
    /// The body of each gmsh entity that belongs to one.
    entity_body: HashMap<i32, usize>,
    /// Sorted contact-surface nodes of each body (see [`Bodies::surface_body_nodes`]).
    surface_body_nodes: Vec<Vec<usize>>,
    /// Whether some body's triangles or tetrahedra take the averaged nodal pressure (its
    /// pattern couples nodes two cells apart).
    pub nodal_pressure: bool,
}

impl Bodies {
    /// Resolve the scene's bodies on the mesh. Errors (`Error::Scene`, naming the key): a body
    /// group that is no physical group of the mesh's dimension, or holds no cell; two bodies
    /// holding the same gmsh entity; a contact group touching cells of different mass kinds;
    /// two layer variants; a body whose own `mass` is modified without a contact group on it.
    pub fn resolve(scene: &Scene, mesh: &Mesh) -> Result<Bodies> {
        Self::resolve_with(scene, mesh, &|_| true, mesh, &|_| {})
    }

    /// The same on a rank's part of the mesh (own cells and ghosts, `partition::local`), with
    /// the contact surface every rank holds: the cell counts are summed over the ranks (the
    /// only collective call, reached by every rank), the layer groups' checks made on the
    /// surface, so every rank gets the same regions, layer and errors.
    pub fn resolve_local(
        world: &SimpleCommunicator,
        scene: &Scene,
        mesh: &Mesh,
        part: &Partition,
        surface: &Surface,
    ) -> Result<Bodies> {
        let own = |c: usize| part.cell_rank[c] as usize == part.rank;
        let sum = |counts: &mut Vec<u64>| {
            let mine = counts.clone();
            world.all_reduce_into(&mine[..], &mut counts[..], SystemOperation::sum());
        };
        Self::resolve_with(scene, mesh, &own, &surface.mesh, &sum)
    }

    /// `resolve` with the cells this rank counts (`own`), the mesh the layer groups are
    /// checked on (`surface`: the whole mesh, or the gathered contact surface) and the sum
    /// of the region cell counts over the ranks.
    fn resolve_with(
        scene: &Scene,
        mesh: &Mesh,
        own: &dyn Fn(usize) -> bool,
        surface: &Mesh,
        sum: &dyn Fn(&mut Vec<u64>),
    ) -> Result<Bodies> {
        let fail = |m: String| Error::Scene(format!("{}: {m}", scene.display_name()));
        let region =
            |name: String, group: Option<String>, spec: MaterialSpec, mass, given| Region {
                name,
                group,
                spec,
                material: Material {
                    mean_dilatation: spec.formulation == Formulation::Mixed,
                    ..Material::from_young_poisson(spec.e, spec.nu, spec.rho)
                },
                mass,
                mass_given: given,
                n_cells: 0,
            };
        let mut regions = vec![region(
            "the cells outside every [[body]]".into(),
            None,
            scene.material,
            scene.mass.kind,
            false,
        )];
        let groups: Vec<String> = scene.mass.layer_groups().iter().map(|g| g.to_string()).collect();
        if scene.bodies.is_empty() {
            let mut n = vec![(0..mesh.cells.len()).filter(|&c| own(c)).count() as u64];
            sum(&mut n);
            let nodal_pressure =
                mixed_bodies_supported(&regions, mesh, own, &|_| 0, sum).map_err(fail)?;
            regions[0].n_cells = n[0] as usize;
            let kind = scene.mass.kind;
            let layer = (kind.is_modified() && !groups.is_empty()).then_some((kind, groups));
            return Ok(Bodies {
                regions,
                cell_region: Vec::new(),
                body_nodes: Vec::new(),
                layer,
                no_layer: vec![false],
                entity_body: HashMap::new(),
                surface_body_nodes: Vec::new(),
                nodal_pressure,
            });
        }
        if scene.bodies.len() >= u16::MAX as usize {
            return Err(fail(format!(
                "{} bodies: at most {} are possible",
                scene.bodies.len(),
                u16::MAX - 1
            )));
        }

        // The gmsh entities of each body (a cell belongs to exactly one entity).
        let mut entity_body: HashMap<i32, usize> = HashMap::new();
        for (i, b) in scene.bodies.iter().enumerate() {
            let key = format!("body[{i}].group = \"{}\"", b.group);
            let Some(g) = mesh.groups.iter().find(|g| g.name == b.group && g.dim == mesh.dim)
            else {
                let have: Vec<String> = (mesh.groups.iter())
                    .filter(|g| g.dim == mesh.dim)
                    .map(|g| format!("\"{}\"", g.name))
                    .collect();
                let other = match mesh.groups.iter().find(|g| g.name == b.group) {
                    Some(g) => format!("\"{}\" has dimension {}; ", g.name, g.dim),
                    None => String::new(),
                };
                return Err(fail(format!(
                    "{key}: no such physical group of dimension {} ({other}the mesh's are {})",
                    mesh.dim,
                    if have.is_empty() { "none".to_string() } else { have.join(", ") }
                )));
            };
            for &e in &g.entities {
                if let Some(j) = entity_body.insert(e, i).filter(|&j| j != i) {
                    return Err(fail(format!(
                        "{key} overlaps body[{j}].group = \"{}\": both hold the gmsh entity {e}; bodies must not overlap",
                        scene.bodies[j].group
                    )));
                }
            }
            regions.push(region(
                format!("body[{i}] \"{}\"", b.group),
                Some(b.group.clone()),
                b.material,
                scene.body_mass(i),
                b.mass.is_some(),
            ));
        }
        let cell_region: Vec<u16> = (mesh.cells.iter())
            .map(|c| entity_body.get(&c.entity).map_or(0, |&i| (i + 1) as u16))
            .collect();
        let mut counts = vec![0u64; regions.len()];
        for (c, &r) in cell_region.iter().enumerate() {
            if own(c) {
                counts[r as usize] += 1;
            }
        }
        sum(&mut counts);
        let nodal_pressure =
            mixed_bodies_supported(&regions, mesh, own, &|c| cell_region[c] as usize, sum)
                .map_err(fail)?;
        for (reg, &n) in regions.iter_mut().zip(&counts) {
            reg.n_cells = n as usize;
        }
        let mut body_nodes = vec![Vec::new(); scene.bodies.len()];
        for (c, &r) in mesh.cells.iter().zip(&cell_region) {
            if r > 0 {
                body_nodes[r as usize - 1].extend_from_slice(&c.nodes());
            }
        }
        for (i, nodes) in body_nodes.iter_mut().enumerate() {
            if counts[i + 1] == 0 {
                return Err(fail(format!(
                    "body[{i}].group = \"{}\" holds no cell of the mesh",
                    scene.bodies[i].group
                )));
            }
            nodes.sort_unstable();
            nodes.dedup();
        }

        // The regions each layer group touches (cells with a node on the group).
        let mut touched = vec![vec![false; regions.len()]; groups.len()];
        if !groups.is_empty() {
            let mut on = vec![0u64; surface.n_nodes()];
            for (k, g) in groups.iter().enumerate().take(64) {
                for e in boundary_group(surface, g)? {
                    for n in e.nodes() {
                        on[n] |= 1 << k;
                    }
                }
            }
            for c in &surface.cells {
                let r = entity_body.get(&c.entity).map_or(0, |&i| i + 1);
                let bits = c.nodes().iter().fold(0u64, |b, &n| b | on[n]);
                for (k, t) in touched.iter_mut().enumerate().take(64) {
                    if bits & (1 << k) != 0 {
                        t[r] = true;
                    }
                }
            }
        }
        let mut layer: Option<(MassKind, Vec<String>)> = None;
        let mut layer_first: &str = "";
        for (g, t) in groups.iter().zip(&touched) {
            let on: Vec<usize> = (0..regions.len()).filter(|&r| t[r]).collect();
            let Some(&first) = on.first() else { continue };
            let kind = regions[first].mass;
            if let Some(&other) = on.iter().find(|&&r| regions[r].mass != kind) {
                return Err(fail(format!(
                    "contact group \"{g}\" touches cells of {} ({} mass) and of {} ({} mass): the mass-free layer along it needs one mass kind; give each body its own contact group",
                    regions[first].name,
                    kind.name(),
                    regions[other].name,
                    regions[other].mass.name()
                )));
            }
            if !kind.is_modified() {
                continue;
            }
            match &mut layer {
                None => {
                    layer = Some((kind, vec![g.clone()]));
                    layer_first = g;
                }
                Some((k, list)) if *k == kind => list.push(g.clone()),
                Some((k, _)) => {
                    return Err(fail(format!(
                        "the mass-free layer would be {} along \"{layer_first}\" and {} along \"{g}\": one run builds one variant; give the bodies the same modified mass",
                        k.name(),
                        kind.name()
                    )));
                }
            }
        }
        let mut no_layer = vec![false; regions.len()];
        for (r, reg) in regions.iter().enumerate() {
            let has_layer = layer.is_some() && touched.iter().any(|t| t[r]);
            if reg.mass.is_modified() && !has_layer {
                if reg.mass_given {
                    let near = if groups.is_empty() {
                        "there is none".to_string()
                    } else {
                        format!("none of {} lies on it", crate::scene::effects::quoted(&groups))
                    };
                    return Err(fail(format!(
                        "body[{}].mass = {} needs a contact group on the body \"{}\" for its mass-free layer, but {near}",
                        r - 1,
                        reg.mass.name(),
                        reg.group.as_deref().unwrap_or_default()
                    )));
                }
                no_layer[r] = true;
            }
        }
        let surface_body_nodes = Vec::new();
        let mut b = Bodies {
            regions,
            cell_region,
            body_nodes,
            layer,
            no_layer,
            entity_body,
            surface_body_nodes,
            nodal_pressure,
        };
        b.surface_body_nodes = b.nodes_of(surface);
        Ok(b)
    }

    /// The sorted nodes of each body's cells in `mesh` (a part of the mesh, or the surface).
    fn nodes_of(&self, mesh: &Mesh) -> Vec<Vec<usize>> {
        let mut nodes = vec![Vec::new(); self.body_nodes.len()];
        for c in &mesh.cells {
            if let Some(&i) = self.entity_body.get(&c.entity) {
                nodes[i].extend_from_slice(&c.nodes());
            }
        }
        for n in &mut nodes {
            n.sort_unstable();
            n.dedup();
        }
        nodes
    }

    /// The sorted contact-surface nodes (`partition::surface`) of `body[i]`'s cells: the
    /// numbering the contact solvers use.
    pub fn surface_body_nodes(&self, i: usize) -> &[usize] {
        &self.surface_body_nodes[i]
    }

    /// The region of a cell (0: outside every body, i + 1: `body[i]`).
    #[inline]
    pub fn region_of(&self, cell: usize) -> usize {
        self.cell_region.get(cell).map_or(0, |&r| r as usize)
    }

    /// Whether some body with cells is finite-strain (the run then steps with Newton).
    pub fn finite_strain(&self) -> bool {
        self.regions.iter().any(|r| r.n_cells > 0 && r.spec.model.is_finite_strain())
    }

    /// The largest `lambda / mu` of the regions with cells (how nearly incompressible the
    /// stiffest body is).
    pub fn lambda_over_mu(&self) -> f64 {
        (self.regions.iter())
            .filter(|r| r.n_cells > 0)
            .map(|r| r.material.lambda / r.material.mu)
            .fold(0.0, f64::max)
    }

    /// The finite-strain law of a cell (`None`: small strain).
    pub fn law(&self, cell: usize) -> Option<crate::fem::hyperelastic::Law> {
        let r = &self.regions[self.region_of(cell)];
        r.spec
            .model
            .is_finite_strain()
            .then(|| crate::fem::hyperelastic::Law::new(r.spec.model, &r.material))
    }

    /// The material of a cell.
    #[inline]
    pub fn material(&self, cell: usize) -> &Material {
        &self.regions[self.region_of(cell)].material
    }

    /// The density and the mass treatment of a cell's element matrix: a modified kind only
    /// where the region has a layer (else consistent).
    #[inline]
    pub fn cell_mass(&self, cell: usize) -> (f64, MassKind) {
        let r = self.region_of(cell);
        (self.regions[r].material.rho, self.mass_of(r))
    }

    /// The mass treatment the cells of region `r` get (consistent for a modified region
    /// without a layer).
    pub fn mass_of(&self, r: usize) -> MassKind {
        if self.no_layer[r] {
            MassKind::Consistent
        } else {
            self.regions[r].mass
        }
    }

    /// The number of `[[body]]`.
    pub fn n_bodies(&self) -> usize {
        self.body_nodes.len()
    }

    /// The sorted nodes of `body[i]`'s cells.
    pub fn body_nodes(&self, i: usize) -> &[usize] {
        &self.body_nodes[i]
    }

    /// Regions with cells.
    pub fn in_use(&self) -> impl Iterator<Item = (usize, &Region)> {
        self.regions.iter().enumerate().filter(|(_, r)| r.n_cells > 0)
    }

    /// The standard (consistent, lumped) mass kinds some cells outside the layer's regions get.
    pub fn standard_masses(&self) -> Vec<MassKind> {
        let used: Vec<MassKind> = self.in_use().map(|(r, _)| self.mass_of(r)).collect();
        MassKind::ALL.into_iter().filter(|k| !k.is_modified() && used.contains(k)).collect()
    }

    /// The step solver's regime: the largest CFL number `c_p tau / h_min` over the regions
    /// with cells, `h_min[r]` the shortest edge of region r (e.g. of its fastest body).
    pub fn regime(&self, tau: f64, h_min: &[f64]) -> Regime {
        let mut worst: Option<Regime> = None;
        for (r, reg) in self.in_use() {
            let s = reg.spec;
            let this = Regime::new(s.e, s.nu, s.rho, tau, h_min[r]);
            if worst.as_ref().is_none_or(|w| this.cfl > w.cfl) {
                worst = Some(this);
            }
        }
        worst.expect("a mesh has cells")
    }
}

/// The mixed formulation on triangles and tetrahedra is the averaged nodal pressure
/// (`assembly::nodal_pressure`): a linear body's is the small-strain operator `G^T D G`, a
/// neo-Hookean body's the nodes' volumes at finite strain. A linear body with it in a
/// finite-strain run (whose Newton loop integrates linear bodies cell by cell) is an error
/// naming both bodies. Returns whether some body has mixed simplices. Collective (`sum` adds
/// over the ranks).
fn mixed_bodies_supported(
    regions: &[Region],
    mesh: &Mesh,
    own: &dyn Fn(usize) -> bool,
    region_of: &dyn Fn(usize) -> usize,
    sum: &dyn Fn(&mut Vec<u64>),
) -> std::result::Result<bool, String> {
    // Per region: its mixed simplices, then its cells.
    let n = regions.len();
    let mut counts = vec![0u64; 2 * n];
    for (c, cell) in mesh.cells.iter().enumerate() {
        if own(c) {
            let r = region_of(c);
            counts[n + r] += 1;
            if regions[r].material.mean_dilatation && cell.kind.is_simplex() {
                counts[r] += 1;
            }
        }
    }
    sum(&mut counts);
    let finite = |r: usize| regions[r].spec.model.is_finite_strain();
    let nodal = (0..n).any(|r| counts[r] > 0);
    let Some(r) = (0..n).find(|&r| counts[r] > 0 && !finite(r)) else { return Ok(nodal) };
    match (0..n).find(|&q| counts[n + q] > 0 && finite(q)) {
        Some(q) => Err(format!(
            "{}: formulation = \"mixed\" on triangles or tetrahedra of a linear body is built for small-strain runs, and {} is finite-strain: make it model = \"neo_hookean\" too, or mesh it with quadrilaterals or hexahedra",
            regions[r].name, regions[q].name
        )),
        None => Ok(nodal),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::element::ElementKind;
    use crate::mesh::{Element, PhysicalGroup};
    use crate::scene::parse;

    /// Four unit quads in a row, x in [0, 4]: cells 0, 1 in entity 1 ("left"), cells 2, 3 in
    /// entity 2 ("right"), glued at x = 2 (nodes 2 and 7). Bottom nodes 0..=4, top 5..=9.
    /// Boundary groups: "lc" (x = 0), "rc" (x = 4), "top1" (the top edge of cell 1, whose
    /// node 7 is also right's); "both" holds the two entities, "void" none with cells.
    fn strip() -> Mesh {
        let coords: Vec<[f64; 3]> =
            (0..10).map(|i| [(i % 5) as f64, (i / 5) as f64, 0.0]).collect();
        let cells = (0..4)
            .map(|k| {
                Element::new(
                    ElementKind::Quad4,
                    &[k, k + 1, k + 6, k + 5],
                    k as u64 + 1,
                    1 + (k / 2) as i32,
                )
            })
            .collect();
        let line = |a, b, tag, ent| Element::new(ElementKind::Line2, &[a, b], tag, ent);
        let boundary = vec![line(0, 5, 101, 11), line(4, 9, 102, 12), line(6, 7, 103, 13)];
        let g = |name: &str, dim, tag, entities: Vec<i32>| PhysicalGroup {
            name: name.into(),
            dim,
            tag,
            entities,
        };
        Mesh {
            dim: 2,
            coords,
            node_tags: (1..=10).collect(),
            cells,
            boundary,
            groups: vec![
                g("left", 2, 1, vec![1]),
                g("right", 2, 2, vec![2]),
                g("both", 2, 3, vec![1, 2]),
                g("void", 2, 4, vec![99]),
                g("lc", 1, 11, vec![11]),
                g("rc", 1, 12, vec![12]),
                g("top1", 1, 13, vec![13]),
            ],
        }
    }

    /// A scene on the strip: E = 1, nu = 0.25, rho = 2, then `rest`.
    fn scene(rest: &str) -> Scene {
        let dir = std::env::temp_dir().join(format!("bodies-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("strip.msh"), "").unwrap();
        let text = format!(
            "[mesh]\nmsh = \"strip.msh\"\n[material]\nE = 1\nnu = 0.25\nrho = 2\n[time]\ntau = 0.1\nsteps = 1\n{rest}\n"
        );
        parse(&text, "strip.toml", &dir).unwrap()
    }

    fn resolve(rest: &str) -> Result<Bodies> {
        Bodies::resolve(&scene(rest), &strip())
    }

    fn error(rest: &str) -> String {
        let m = resolve(rest).unwrap_err().to_string();
        assert!(!m.contains('\n') && m.starts_with("scene error: strip.toml: "), "{m}");
        m
    }

    const PAIR: &str = "[contact]\nslave = \"lc\"\nmaster = \"rc\"\n";

    #[test]
    fn each_cell_gets_its_body_material() {
        let b = resolve("[[body]]\ngroup = \"right\"\nE = 4\nrho = 3").unwrap();
        assert_eq!((0..4).map(|c| b.region_of(c)).collect::<Vec<_>>(), vec![0, 0, 1, 1]);
        let (default, right) = (
            Material::from_young_poisson(1.0, 0.25, 2.0),
            Material::from_young_poisson(4.0, 0.25, 3.0),
        );
        assert_eq!(*b.material(1), default);
        assert_eq!(*b.material(2), right);
        assert_eq!(b.cell_mass(0), (2.0, MassKind::Consistent));
        assert_eq!(b.cell_mass(3), (3.0, MassKind::Consistent));
        assert_eq!(b.body_nodes(0), &[2, 3, 4, 7, 8, 9]);
        assert_eq!((b.regions[0].n_cells, b.regions[1].n_cells), (2, 2));
        // Without bodies: one region, no per-cell table.
        let b = resolve("").unwrap();
        assert_eq!((b.n_bodies(), b.region_of(3), b.regions.len()), (0, 0, 1));
        assert_eq!(b.regions[0].n_cells, 4);
    }

    #[test]
    fn body_groups_are_checked_against_the_mesh() {
        let m = error("[[body]]\ngroup = \"left\"\n[[body]]\ngroup = \"nope\"");
        assert!(
            m.contains("body[1].group = \"nope\": no such physical group of dimension 2 (the mesh's are \"left\", \"right\", \"both\", \"void\")"),
            "{m}"
        );
        let m = error("[[body]]\ngroup = \"lc\"");
        assert!(m.contains("body[0].group = \"lc\": no such physical group of dimension 2 (\"lc\" has dimension 1;"), "{m}");
        let m = error("[[body]]\ngroup = \"left\"\nE = 2\n[[body]]\ngroup = \"both\"\nrho = 1");
        assert!(m.contains("body[1].group = \"both\" overlaps body[0].group = \"left\": both hold the gmsh entity 1"), "{m}");
        let m = error("[[body]]\ngroup = \"void\"");
        assert!(m.contains("body[0].group = \"void\" holds no cell"), "{m}");
    }

    #[test]
    fn the_layer_runs_only_along_bodies_with_a_modified_mass() {
        // Default modified1, left consistent: the layer along "rc" only.
        let b = resolve(&format!("[[body]]\ngroup = \"left\"\nmass = \"consistent\"\n[mass]\nkind = \"modified1\"\n{PAIR}")).unwrap();
        assert_eq!(b.layer, Some((MassKind::Modified1, vec!["rc".to_string()])));
        assert_eq!(b.cell_mass(0).1, MassKind::Consistent);
        assert_eq!(b.cell_mass(3).1, MassKind::Modified1);
        assert_eq!(b.standard_masses(), vec![MassKind::Consistent]);
        // Both modified: along both groups; both consistent (default and body): none.
        let b = resolve(&format!(
            "[[body]]\ngroup = \"left\"\nE = 3\n[mass]\nkind = \"modified0\"\n{PAIR}"
        ))
        .unwrap();
        assert_eq!(b.layer, Some((MassKind::Modified0, vec!["lc".to_string(), "rc".to_string()])));
        assert!(b.standard_masses().is_empty());
        let b =
            resolve(&format!("[[body]]\ngroup = \"right\"\nmass = \"lumped\"\n{PAIR}")).unwrap();
        assert_eq!(b.layer, None);
        assert_eq!(b.standard_masses(), vec![MassKind::Consistent, MassKind::Lumped]);
        // An inherited modified mass without a contact group on the body: consistent there.
        let b = resolve("[[body]]\ngroup = \"right\"\nE = 2\n[mass]\nkind = \"modified1\"\ncontact_boundary = \"lc\"").unwrap();
        assert_eq!(b.layer, Some((MassKind::Modified1, vec!["lc".to_string()])));
        assert_eq!(
            (b.cell_mass(0).1, b.cell_mass(2).1),
            (MassKind::Modified1, MassKind::Consistent)
        );
        assert_eq!(b.mass_of(1), MassKind::Consistent);
        assert_eq!(b.standard_masses(), vec![MassKind::Consistent]);
    }

    #[test]
    fn layer_conflicts_are_errors_naming_the_key() {
        // The body's own modified mass, but no contact group on it.
        let m = error(
            "[[body]]\ngroup = \"right\"\nmass = \"modified1\"\n[mass]\ncontact_boundary = \"lc\"",
        );
        assert!(m.contains("body[0].mass = modified1 needs a contact group on the body \"right\" for its mass-free layer, but none of \"lc\" lies on it"), "{m}");
        // A group whose layer cells have different kinds (node 7 is on both bodies).
        let m = error("[[body]]\ngroup = \"right\"\nmass = \"lumped\"\n[mass]\nkind = \"modified1\"\ncontact_boundary = \"top1\"");
        assert!(
            m.contains("contact group \"top1\" touches cells of the cells outside every [[body]] (modified1 mass) and of body[0] \"right\" (lumped mass)"),
            "{m}"
        );
        // Two variants.
        let m = error(&format!("[[body]]\ngroup = \"right\"\nmass = \"modified0\"\n[mass]\nkind = \"modified1\"\n{PAIR}"));
        assert!(
            m.contains(
                "modified1 along \"lc\" and modified0 along \"rc\": one run builds one variant"
            ),
            "{m}"
        );
        // A missing contact group is the contact group's error.
        let m = resolve("[[body]]\ngroup = \"right\"\n[mass]\nkind = \"modified1\"\ncontact_boundary = \"nope\"")
            .unwrap_err()
            .to_string();
        assert!(m.contains("contact group") && m.contains("\"nope\""), "{m}");
    }

    #[test]
    fn the_regime_is_the_fastest_bodys() {
        let b = resolve("[[body]]\ngroup = \"right\"\nE = 4").unwrap();
        let c = Material::from_young_poisson(1.0, 0.25, 2.0).wave_speeds().0;
        // Right: twice the wave speed on the same h; left's h halved gives the same.
        let r = b.regime(0.1, &[1.0, 1.0]);
        assert!((r.wave_speed - 2.0 * c).abs() < 1e-14 * c && (r.cfl - 0.2 * c).abs() < 1e-14);
        let r = b.regime(0.1, &[0.25, 1.0]);
        assert!((r.cfl - 0.4 * c).abs() < 1e-14, "{}", r.cfl);
        // A region without cells does not count.
        let b = resolve("[[body]]\ngroup = \"both\"\nrho = 8").unwrap();
        let r = b.regime(0.1, &[1e-9, 1.0]);
        assert!((r.wave_speed - c / 2.0).abs() < 1e-14, "{}", r.wave_speed);
    }
}
