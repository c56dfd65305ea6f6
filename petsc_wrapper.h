/* Headers bindgen turns into src/petsc/ffi.rs (via OUT_DIR/petsc_bindings.rs). */
#include <petscsys.h>
#include <petscis.h>
#include <petscvec.h>
#include <petscmat.h>
#include <petscksp.h>
