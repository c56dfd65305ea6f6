//! massfree: parallel finite elements for dynamic elasticity with contact, with the
//! mass-free surface layer of Hager & Wohlmuth (SIAM J. Numer. Anal. 2009).
//!
//! One module per concept; README.md ("How it works") lists them and maps each equation of
//! the paper to the function that implements it. Module docs cite `METHOD.md`, the method
//! restated for implementation: it is not in this repository but beside it, in
//! `../shared/reference/METHOD.md` (with the paper, `hager-wohlmuth-2009.txt`).

pub mod assembly;
pub mod bodies;
pub mod console;
pub mod contact;
pub mod error;
pub mod fem;
pub mod io;
pub mod mass;
pub mod mesh;
pub mod options;
pub mod partition;
pub mod petsc;
pub mod phase;
pub mod post;
pub mod report;
pub mod rows;
pub mod scene;
pub mod simulation;
pub mod stability;
pub mod stress_output;
pub mod study;
pub mod suite;
pub mod time;

pub use error::{Error, Result};
