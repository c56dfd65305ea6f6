//! massfree: parallel finite elements for dynamic elasticity with contact, with the
//! mass-free surface layer of Hager & Wohlmuth (SIAM J. Numer. Anal. 2009).
//!
//! One module per concept; docs/CONTRIBUTING.md lists them. Module docs cite
//! docs/method.md, the method restated for implementation, whose last section maps each part
//! of the paper to the module that implements it.

pub mod assembly;
pub mod bodies;
pub mod comm;
pub mod console;
pub mod contact;
pub mod error;
pub mod fem;
pub mod io;
pub mod mass;
pub mod mesh;
pub mod partition;
pub mod petsc;
pub mod phase;
pub mod post;
pub mod report;
pub mod rows;
pub mod run;
pub mod scene;
pub mod stability;
pub mod study;
pub mod suite;
pub mod time;

pub use error::{Error, Result};
