//! PETSc initialization guard and the options database.

use super::conv::{cstring, from_cstr};
use super::ffi;
use crate::error::{Error, Result};
use std::ffi::CString;
use std::os::raw::{c_char, c_int};
use std::ptr;

/// True while PETSc is initialized and not yet finalized.
pub(crate) fn is_live() -> bool {
    let mut init = ffi::PetscBool_PETSC_FALSE;
    let mut fin = ffi::PetscBool_PETSC_FALSE;
    // SAFETY: both functions only read global flags and may be called at any time.
    let ok = unsafe { ffi::PetscInitialized(&mut init) == 0 && ffi::PetscFinalized(&mut fin) == 0 };
    ok && init == ffi::PetscBool_PETSC_TRUE && fin == ffi::PetscBool_PETSC_FALSE
}

/// PETSc init guard: `PetscInitialize` on creation, `PetscFinalize` on drop.
///
/// MPI must already be initialized by the `mpi` crate (`mpi::initialize()`), so PETSc does
/// not own MPI and will not finalize it. Declare the guard right after the MPI universe and
/// before any other PETSc handle, so that it drops after all of them:
///
/// ```text
/// let universe = mpi::initialize().unwrap();
/// let petsc = Petsc::init(&std::env::args().collect::<Vec<_>>(), "help")?;
/// // ... Vector / Matrix / Ksp ...
/// ```
pub struct Petsc {
    rank: usize,
    size: usize,
    // PETSc keeps pointers to argc/argv (PetscGetArgs), so they live as long as the guard.
    _args: Vec<CString>,
    _argv: Vec<*mut c_char>,
}

impl Petsc {
    /// Initializes PETSc with `args` as the command line (`args[0]` is the program name, the
    /// rest are PETSc options such as `-ksp_type cg`). Fails if MPI is not initialized or if
    /// PETSc was already initialized (a second guard would finalize it twice).
    pub fn init(args: &[String], help: &str) -> Result<Petsc> {
        let mut mpi_init: c_int = 0;
        // SAFETY: MPI_Initialized may be called at any time, even before MPI_Init.
        unsafe { ffi::MPI_Initialized(&mut mpi_init) };
        if mpi_init == 0 {
            return Err(Error::Mpi(
                "MPI is not initialized: call mpi::initialize() before Petsc::init".into(),
            ));
        }
        let mut flag = ffi::PetscBool_PETSC_FALSE;
        // SAFETY: reads a global flag; callable before PetscInitialize.
        chk!(ffi::PetscInitialized(&mut flag))?;
        let mut fin = ffi::PetscBool_PETSC_FALSE;
        // SAFETY: as above.
        chk!(ffi::PetscFinalized(&mut fin))?;
        if flag == ffi::PetscBool_PETSC_TRUE || fin == ffi::PetscBool_PETSC_TRUE {
            return Err(Error::Petsc {
                call: "PetscInitialize (already initialized or finalized in this process)".into(),
                code: 73,
                location: format!("{}:{}", file!(), line!()),
                message: String::new(),
            });
        }

        let mut c_args = args.iter().map(|a| cstring(a)).collect::<Result<Vec<CString>>>()?;
        if c_args.is_empty() {
            c_args.push(cstring("massfree")?);
        }
        let mut argv: Vec<*mut c_char> = c_args.iter().map(|a| a.as_ptr() as *mut c_char).collect();
        argv.push(ptr::null_mut()); // C convention: argv[argc] == NULL
        let mut argc = (argv.len() - 1) as c_int;
        let mut argv_ptr = argv.as_mut_ptr();
        let help = cstring(help)?;
        // SAFETY: argc/argv describe NUL-terminated strings kept alive in the returned guard;
        // PETSc does not write through argv; a NULL file means "no options file".
        chk!(ffi::PetscInitialize(&mut argc, &mut argv_ptr, ptr::null(), help.as_ptr()))?;
        // Errors come back as `Result`s with PETSc's message in them: keep PETSc from printing
        // its multi-line traceback (the command line's -on_error_* options still apply).
        // SAFETY: PetscReturnErrorHandler has the handler signature; PETSc is initialized.
        chk!(ffi::PetscPushErrorHandler(Some(ffi::PetscReturnErrorHandler), ptr::null_mut()))?;
        // Needed for memory_maximum() to report anything.
        // SAFETY: PETSc is initialized.
        chk!(ffi::PetscMemorySetGetMaximumUsage())?;

        let comm = Self::comm_world();
        let (mut rank, mut size): (c_int, c_int) = (0, 1);
        // SAFETY: PETSC_COMM_WORLD is a valid communicator after PetscInitialize.
        let rc =
            unsafe { ffi::MPI_Comm_rank(comm, &mut rank) + ffi::MPI_Comm_size(comm, &mut size) };
        if rc != 0 {
            return Err(Error::Mpi(format!("MPI_Comm_rank/size failed with code {rc}")));
        }
        Ok(Petsc { rank: rank as usize, size: size as usize, _args: c_args, _argv: argv })
    }

    /// This process's rank in `PETSC_COMM_WORLD`.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// Number of processes in `PETSC_COMM_WORLD`.
    pub fn size(&self) -> usize {
        self.size
    }

    /// The raw `PETSC_COMM_WORLD` (null before `Petsc::init`).
    pub fn comm_world() -> ffi::MPI_Comm {
        // SAFETY: plain read of a pointer-sized global that PETSc sets once in PetscInitialize.
        unsafe { ffi::PETSC_COMM_WORLD }
    }

    /// The raw `MPI_COMM_SELF`, for objects private to one rank (e.g. a rank's own
    /// factorization).
    pub fn comm_self() -> ffi::MPI_Comm {
        use mpi::raw::AsRaw;
        mpi::topology::SimpleCommunicator::self_comm().as_raw().0.cast()
    }

    /// Enters one of the program's own options, e.g. `options_set("-ksp_type", Some("cg"))`
    /// (the leading `-` is required). Only objects configured afterwards
    /// (`set_from_options`) see it. The program's own options are never reported as unused
    /// ([`Petsc::options_unused`]); an option the user gave elsewhere is entered with
    /// [`Petsc::options_set_given`].
    pub fn options_set(name: &str, value: Option<&str>) -> Result<()> {
        Self::options_set_given(name, value)?;
        super::options::record_entered(name);
        Ok(())
    }

    /// Removes a global option (no error if it was not set).
    pub fn options_clear(name: &str) -> Result<()> {
        let n = cstring(name)?;
        // SAFETY: valid C string; global database.
        chk!(ffi::PetscOptionsClearValue(ptr::null_mut(), n.as_ptr()))
    }

    /// Whether the option was given (with or without a value). Like every read, this marks
    /// the option used.
    pub fn options_has(name: &str) -> Result<bool> {
        let n = cstring(name)?;
        let mut set = ffi::PetscBool_PETSC_FALSE;
        // SAFETY: valid C string and out-pointer; global database, no prefix.
        chk!(ffi::PetscOptionsHasName(ptr::null_mut(), ptr::null(), n.as_ptr(), &mut set))?;
        Ok(set == ffi::PetscBool_PETSC_TRUE)
    }

    /// Integer option value, `None` if not given.
    pub fn options_get_int(name: &str) -> Result<Option<i32>> {
        options_get(name, ffi::PetscOptionsGetInt, "PetscOptionsGetInt")
    }

    /// Real option value, `None` if not given.
    pub fn options_get_real(name: &str) -> Result<Option<f64>> {
        options_get(name, ffi::PetscOptionsGetReal, "PetscOptionsGetReal")
    }

    /// String option value (at most 4095 bytes), `None` if not given.
    pub fn options_get_string(name: &str) -> Result<Option<String>> {
        let n = cstring(name)?;
        let mut buf = vec![0 as c_char; 4096];
        let mut set = ffi::PetscBool_PETSC_FALSE;
        // SAFETY: PETSc writes at most buf.len() bytes including the terminating NUL.
        chk!(ffi::PetscOptionsGetString(
            ptr::null_mut(),
            ptr::null(),
            n.as_ptr(),
            buf.as_mut_ptr(),
            buf.len(),
            &mut set
        ))?;
        Ok((set == ffi::PetscBool_PETSC_TRUE).then(|| from_cstr(buf.as_ptr())))
    }

    /// Runs `f` with PETSc's error printing switched off (errors are still returned as
    /// `Err`). Meant for checks that expect a failure and do not want a traceback on stderr.
    pub fn with_quiet_errors<R>(&self, f: impl FnOnce() -> R) -> R {
        // SAFETY: PetscReturnErrorHandler has the handler signature; the push is undone below.
        let pushed = unsafe {
            ffi::PetscPushErrorHandler(Some(ffi::PetscReturnErrorHandler), ptr::null_mut())
        } == 0;
        let r = f();
        if pushed {
            // SAFETY: pops exactly the handler pushed above.
            unsafe { ffi::PetscPopErrorHandler() };
        }
        r
    }
}

impl Drop for Petsc {
    fn drop(&mut self) {
        if is_live() {
            // SAFETY: PETSc is initialized by this guard; all handles are expected to be gone.
            let code = unsafe { ffi::PetscFinalize() };
            if code != 0 {
                eprintln!("PetscFinalize returned error code {code}");
            }
        }
    }
}

/// The signature shared by `PetscOptionsGetInt` and `PetscOptionsGetReal`.
type OptionsGetter<T> = unsafe extern "C" fn(
    ffi::PetscOptions,
    *const c_char,
    *const c_char,
    *mut T,
    *mut ffi::PetscBool,
) -> ffi::PetscErrorCode;

/// A scalar option value from the global database (no prefix), `None` if not given.
fn options_get<T: Default>(name: &str, get: OptionsGetter<T>, call: &str) -> Result<Option<T>> {
    let n = cstring(name)?;
    let mut val = T::default();
    let mut set = ffi::PetscBool_PETSC_FALSE;
    // SAFETY: valid C string and out-pointers of the getter's value type; global database.
    let code = unsafe { get(ptr::null_mut(), ptr::null(), n.as_ptr(), &mut val, &mut set) };
    super::conv::check(code, call, file!(), line!())?;
    Ok((set == ffi::PetscBool_PETSC_TRUE).then_some(val))
}

/// Errors unless PETSc is initialized and not finalized: creating or destroying objects
/// outside that window is undefined behaviour in C, so constructors check it first.
pub(crate) fn ensure_live() -> Result<()> {
    if is_live() {
        Ok(())
    } else {
        Err(Error::Petsc {
            call: "PetscInitialized (Petsc::init not called, or PETSc already finalized)".into(),
            code: 73, // PETSC_ERR_ORDER: object in wrong state
            location: format!("{}:{}", file!(), line!()),
            message: String::new(),
        })
    }
}
