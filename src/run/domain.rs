//! The run's [`Domain`]: what every phase reads and none changes.

use std::rc::Rc;

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::bodies::Bodies;
use crate::mesh::Mesh;
use crate::partition::surface::Surface;
use crate::partition::Partition;
use crate::scene::Scene;

/// What every phase of a run reads and none changes: the communicator, the scene, the mesh
/// with its partition and bodies, and the number of steps.
pub struct Domain<'a> {
    pub world: &'a SimpleCommunicator,
    pub scene: Scene,
    /// The cells of each `[[body]]`: material and mass treatment per cell, the layer's groups.
    pub bodies: Bodies,
    /// Shared with the loads and the stress output.
    pub mesh: Rc<Mesh>,
    pub part: Rc<Partition>,
    /// The contact surface, whole on every rank (contact groups and the layer's groups).
    pub surface: Rc<Surface>,
    pub rank: usize,
    pub size: usize,
    /// The steps to run: the scene's, or the command line's `--steps`.
    pub n_steps: usize,
    /// The largest extent of the mesh's bounding box (`stability::body_size`, all ranks).
    pub body_size: f64,
}

/// The largest extent of the bounding box of all ranks' nodes (collective).
pub fn body_size(world: &SimpleCommunicator, mesh: &Mesh) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for x in &mesh.coords {
        for i in 0..3 {
            lo[i] = lo[i].min(x[i]);
            hi[i] = hi[i].max(x[i]);
        }
    }
    let (mut glo, mut ghi) = ([0.0; 3], [0.0; 3]);
    world.all_reduce_into(&lo[..], &mut glo[..], SystemOperation::min());
    world.all_reduce_into(&hi[..], &mut ghi[..], SystemOperation::max());
    crate::stability::body_size(&[glo, ghi])
}

impl Domain<'_> {
    /// The effects line, with the mass treatment as the mesh resolved it.
    pub fn effects(&self) -> String {
        let layer = self.bodies.layer.as_ref().map(|(k, g)| (*k, g.as_slice()));
        self.scene.effects().resolve(self.bodies.standard_masses(), layer).summary()
    }
}
