//! The options database as an application reads it: typed reads with PETSc's own semantics
//! (a bare boolean flag is true; `true|false|1|0|yes|no|on|off`), self-documenting blocks of
//! options that `-help` lists like PETSc's own objects do (`PetscOptionsBegin` ...
//! `PetscOptionsEnd`), and the options that nothing used (PETSc's `-options_left`).
//!
//! A value PETSc cannot read is an `Error::Usage` naming the option and the value, e.g.
//! `-newton_monitor maybe: give true or false (also 1|0, yes|no, on|off)`.

use std::collections::BTreeSet;
use std::ffi::CString;
use std::os::raw::c_char;
use std::ptr;
use std::sync::Mutex;

use super::conv::{cstring, from_cstr, petsc_bool};
use super::ffi;
use super::init::Petsc;
use crate::error::{Error, Result};

// The functions behind PETSc's option-block macros (`PetscOptionsBegin`, `PetscOptionsReal`,
// ...; petscoptions.h). build.rs leaves `*_Private` functions out of the generated bindings,
// so the ones used here are declared by hand, with the prototypes of PETSc 3.18.
extern "C" {
    static PetscOptionsPublish: ffi::PetscBool;
    fn PetscOptionsBegin_Private(
        items: *mut ffi::PetscOptionItems,
        comm: ffi::MPI_Comm,
        prefix: *const c_char,
        title: *const c_char,
        mansec: *const c_char,
    ) -> ffi::PetscErrorCode;
    fn PetscOptionsEnd_Private(items: *mut ffi::PetscOptionItems) -> ffi::PetscErrorCode;
    fn PetscOptionsReal_Private(
        items: *mut ffi::PetscOptionItems,
        opt: *const c_char,
        text: *const c_char,
        man: *const c_char,
        current: ffi::PetscReal,
        value: *mut ffi::PetscReal,
        set: *mut ffi::PetscBool,
    ) -> ffi::PetscErrorCode;
    fn PetscOptionsInt_Private(
        items: *mut ffi::PetscOptionItems,
        opt: *const c_char,
        text: *const c_char,
        man: *const c_char,
        current: ffi::PetscInt,
        value: *mut ffi::PetscInt,
        set: *mut ffi::PetscBool,
        lb: ffi::PetscInt,
        ub: ffi::PetscInt,
    ) -> ffi::PetscErrorCode;
    fn PetscOptionsBool_Private(
        items: *mut ffi::PetscOptionItems,
        opt: *const c_char,
        text: *const c_char,
        man: *const c_char,
        current: ffi::PetscBool,
        value: *mut ffi::PetscBool,
        set: *mut ffi::PetscBool,
    ) -> ffi::PetscErrorCode;
    fn PetscOptionsString_Private(
        items: *mut ffi::PetscOptionItems,
        opt: *const c_char,
        text: *const c_char,
        man: *const c_char,
        current: *const c_char,
        value: *mut c_char,
        len: usize,
        set: *mut ffi::PetscBool,
    ) -> ffi::PetscErrorCode;
    fn PetscOptionsEList_Private(
        items: *mut ffi::PetscOptionItems,
        opt: *const c_char,
        text: *const c_char,
        man: *const c_char,
        list: *const *const c_char,
        ntext: ffi::PetscInt,
        current: *const c_char,
        value: *mut ffi::PetscInt,
        set: *mut ffi::PetscBool,
    ) -> ffi::PetscErrorCode;
}

/// Where `-help` sends the reader for the application's options (PETSc prints a manual page
/// name in this place).
const MAN: &[u8] = b"docs/user-guide.md\0";

/// What a boolean option accepts, for error messages.
const BOOL_VALUES: &str = "give true or false (also 1|0, yes|no, on|off)";

/// Options the program entered itself ([`Petsc::options_set`]): defaults under the command
/// line's and the scene's options, never reported as unused.
static ENTERED: Mutex<BTreeSet<String>> = Mutex::new(BTreeSet::new());

/// Options `PetscFinalize` reads (after any check an application can make before it): never
/// reported as unused.
const READ_AT_FINALIZE: [&str; 24] = [
    "citations",
    "get_total_flops",
    "log",
    "log_all",
    "log_mpe",
    "log_view",
    "log_view_gpu_time",
    "log_view_memory",
    "malloc_debug",
    "malloc_dump",
    "malloc_test",
    "malloc_view",
    "malloc_view_threshold",
    "memory_view",
    "mpi_linear_solver_server",
    "mpidump",
    "no_signal_handler",
    "nox",
    "nox_warning",
    "objects_dump",
    "options_left",
    "options_view",
    "saw_options",
    "x_virtual",
];

/// An option name as PETSc compares them: without the leading `-`, lower case.
fn key(name: &str) -> String {
    name.trim_start_matches('-').to_ascii_lowercase()
}

pub(super) fn record_entered(name: &str) {
    if let Ok(mut set) = ENTERED.lock() {
        set.insert(key(name));
    }
}

/// The error for an option whose value PETSc could not read: the option, the value as given,
/// and what it takes.
fn bad_value(name: &str, what: &str) -> Error {
    match Petsc::options_get_string(name) {
        Ok(Some(v)) if !v.is_empty() => Error::Usage(format!("{name} {v}: {what}")),
        _ => Error::Usage(format!("{name} needs a value: {what}")),
    }
}

impl Petsc {
    /// A boolean option read as PETSc reads booleans: `None` if not given; alone (`-name`) it
    /// is true; `true|false|1|0|yes|no|on|off` in any case. Another value is an error naming
    /// the option.
    pub fn options_get_bool(name: &str) -> Result<Option<bool>> {
        let n = cstring(name)?;
        let mut val = ffi::PetscBool_PETSC_FALSE;
        let mut set = ffi::PetscBool_PETSC_FALSE;
        // SAFETY: valid C string and out-pointers; global database, no prefix.
        let code = unsafe {
            ffi::PetscOptionsGetBool(ptr::null_mut(), ptr::null(), n.as_ptr(), &mut val, &mut set)
        };
        if code != 0 {
            return Err(bad_value(name, BOOL_VALUES));
        }
        Ok((set == ffi::PetscBool_PETSC_TRUE).then_some(val == ffi::PetscBool_PETSC_TRUE))
    }

    /// Enters an option that the user gave outside the command line (the scene's `[solver]
    /// options`): unlike [`Petsc::options_set`], it is reported if nothing uses it.
    pub fn options_set_given(name: &str, value: Option<&str>) -> Result<()> {
        let n = cstring(name)?;
        let v = value.map(cstring).transpose()?;
        let vp = v.as_ref().map_or(ptr::null(), |v| v.as_ptr());
        // SAFETY: valid C strings; a null options object means the global database.
        chk!(ffi::PetscOptionsSetValue(ptr::null_mut(), n.as_ptr(), vp))
    }

    /// Whether the option was given (with or without a value), without marking it used as
    /// [`Petsc::options_has`] does: an option that only this check saw is still reported as
    /// unused.
    pub fn options_given(name: &str) -> Result<bool> {
        let k = key(name);
        Ok(Self::options_used(name)? || left()?.iter().any(|n| key(n) == k))
    }

    /// Whether something read the option (`PetscOptionsUsed`), on this rank; false if it was
    /// not given.
    pub fn options_used(name: &str) -> Result<bool> {
        let n = cstring(&key(name))?;
        let mut used = ffi::PetscBool_PETSC_FALSE;
        // SAFETY: valid C string and out-pointer; global database.
        chk!(ffi::PetscOptionsUsed(ptr::null_mut(), n.as_ptr(), &mut used))?;
        Ok(used == ffi::PetscBool_PETSC_TRUE)
    }

    /// The options given on the command line or in the scene that nothing read on this rank
    /// so far, as `-name` (`PetscOptionsLeftGet`), without those the program entered itself
    /// and those `PetscFinalize` reads.
    pub fn options_unused() -> Result<Vec<String>> {
        let entered = ENTERED.lock().map(|s| s.clone()).unwrap_or_default();
        Ok(left()?
            .into_iter()
            .filter(|name| {
                let k = key(name);
                !entered.contains(&k) && !READ_AT_FINALIZE.contains(&k.as_str())
            })
            .map(|name| if name.starts_with('-') { name } else { format!("-{name}") })
            .collect())
    }
}

/// The names of the options in the database that nothing read on this rank so far
/// (`PetscOptionsLeftGet`, which marks nothing).
fn left() -> Result<Vec<String>> {
    let mut n: ffi::PetscInt = 0;
    let mut names: *mut *mut c_char = ptr::null_mut();
    let mut values: *mut *mut c_char = ptr::null_mut();
    // SAFETY: out-pointers; PETSc allocates the two arrays, freed by the restore below.
    chk!(ffi::PetscOptionsLeftGet(ptr::null_mut(), &mut n, &mut names, &mut values))?;
    // SAFETY: `names` holds `n` valid C strings.
    let left = (0..super::conv::to_usize(n)).map(|i| from_cstr(unsafe { *names.add(i) })).collect();
    // SAFETY: gives back exactly what PetscOptionsLeftGet allocated.
    chk!(ffi::PetscOptionsLeftRestore(ptr::null_mut(), &mut n, &mut names, &mut values))?;
    Ok(left)
}

/// One block of an application's options, as `PetscOptionsBegin` ... `PetscOptionsEnd` make
/// it in C: each read also registers the option with its description and default, which
/// `-help` prints (rank 0) under the block's title, and marks it used.
pub struct OptionsBlock {
    items: Box<ffi::PetscOptionItems>,
}

impl OptionsBlock {
    /// Runs `body` between `PetscOptionsBegin` and `PetscOptionsEnd` on `PETSC_COMM_WORLD`
    /// (collective: every rank reads the same options). Like the C macros, it runs `body`
    /// more than once when PETSc publishes options to a GUI (`-saws_options`); the last
    /// result is returned.
    pub fn read<T>(title: &str, mut body: impl FnMut(&mut OptionsBlock) -> Result<T>) -> Result<T> {
        super::init::ensure_live()?;
        let title = cstring(title)?;
        let mut block = OptionsBlock { items: Box::default() };
        // SAFETY: a global flag PETSc sets once in PetscInitialize.
        let publish = unsafe { PetscOptionsPublish } == ffi::PetscBool_PETSC_TRUE;
        block.items.count = if publish { -1 } else { 1 };
        let mut result = None;
        while block.items.count < 2 {
            // SAFETY: `items` is zeroed (as the macro's PetscMemzero) or left by the previous
            // pass; a null prefix and man section are allowed.
            chk!(PetscOptionsBegin_Private(
                &mut *block.items,
                Petsc::comm_world(),
                ptr::null(),
                title.as_ptr(),
                ptr::null()
            ))?;
            let r = body(&mut block);
            // SAFETY: ends the block begun above (also after a failed read, to free it).
            let end = chk!(PetscOptionsEnd_Private(&mut *block.items));
            let value = r?;
            end?;
            result = Some(value);
            block.items.count += 1;
        }
        result.ok_or_else(|| Error::Internal("options block ran no pass".into()))
    }

    fn names(name: &str, text: &str) -> Result<(CString, CString)> {
        Ok((cstring(name)?, cstring(text)?))
    }

    /// A real option, `default` if not given.
    pub fn real(&mut self, name: &str, text: &str, default: f64) -> Result<f64> {
        let (n, t) = Self::names(name, text)?;
        let (mut v, mut set) = (default, ffi::PetscBool_PETSC_FALSE);
        // SAFETY: a begun block; valid C strings and out-pointers.
        let code = unsafe {
            PetscOptionsReal_Private(
                &mut *self.items,
                n.as_ptr(),
                t.as_ptr(),
                MAN.as_ptr().cast(),
                default,
                &mut v,
                &mut set,
            )
        };
        if code != 0 || (set == ffi::PetscBool_PETSC_FALSE && Petsc::options_given(name)?) {
            return Err(bad_value(name, "give a number"));
        }
        Ok(v)
    }

    /// A real option whose default depends on the run (`default` describes it for `-help`):
    /// `None` if not given.
    pub fn real_or(&mut self, name: &str, text: &str, default: &str) -> Result<Option<f64>> {
        if !self.string(name, text, default)? {
            return Ok(None);
        }
        match Petsc::options_get_real(name) {
            Ok(Some(v)) => Ok(Some(v)),
            _ => Err(bad_value(name, "give a number")),
        }
    }

    /// A whole-number option, `default` if not given.
    pub fn int(&mut self, name: &str, text: &str, default: i32) -> Result<i32> {
        let (n, t) = Self::names(name, text)?;
        let (mut v, mut set) = (default, ffi::PetscBool_PETSC_FALSE);
        // SAFETY: a begun block; valid C strings and out-pointers; the bounds of PetscInt.
        let code = unsafe {
            PetscOptionsInt_Private(
                &mut *self.items,
                n.as_ptr(),
                t.as_ptr(),
                MAN.as_ptr().cast(),
                default,
                &mut v,
                &mut set,
                ffi::PetscInt::MIN,
                ffi::PetscInt::MAX,
            )
        };
        if code != 0 || (set == ffi::PetscBool_PETSC_FALSE && Petsc::options_given(name)?) {
            return Err(bad_value(name, "give a whole number"));
        }
        Ok(v)
    }

    /// A boolean option (PETSc's semantics, see [`Petsc::options_get_bool`]), `default` if not
    /// given.
    pub fn bool(&mut self, name: &str, text: &str, default: bool) -> Result<bool> {
        let (n, t) = Self::names(name, text)?;
        let (mut v, mut set) = (petsc_bool(default), ffi::PetscBool_PETSC_FALSE);
        // SAFETY: a begun block; valid C strings and out-pointers.
        let code = unsafe {
            PetscOptionsBool_Private(
                &mut *self.items,
                n.as_ptr(),
                t.as_ptr(),
                MAN.as_ptr().cast(),
                petsc_bool(default),
                &mut v,
                &mut set,
            )
        };
        if code != 0 {
            return Err(bad_value(name, BOOL_VALUES));
        }
        Ok(v == ffi::PetscBool_PETSC_TRUE)
    }

    /// A boolean option whose default depends on the run (`default` describes it for
    /// `-help`): `None` if not given.
    pub fn bool_or(&mut self, name: &str, text: &str, default: &str) -> Result<Option<bool>> {
        if !self.string(name, text, default)? {
            return Ok(None);
        }
        Petsc::options_get_bool(name)
    }

    /// One of `choices` (case does not matter), the index of `default` if not given; another
    /// value is an error naming the option and the choices.
    pub fn choice(
        &mut self,
        name: &str,
        text: &str,
        choices: &[&str],
        default: usize,
    ) -> Result<usize> {
        let (n, t) = Self::names(name, text)?;
        let list = choices.iter().map(|c| cstring(c)).collect::<Result<Vec<CString>>>()?;
        let ptrs: Vec<*const c_char> = list.iter().map(|c| c.as_ptr()).collect();
        let count = super::conv::to_int(choices.len(), "choices")?;
        let mut v = super::conv::to_int(default, "default choice")?;
        let mut set = ffi::PetscBool_PETSC_FALSE;
        // SAFETY: a begun block; valid C strings; `ptrs` holds `count` of them and, like
        // `list`, outlives the call; `current` is one of them.
        let code = unsafe {
            PetscOptionsEList_Private(
                &mut *self.items,
                n.as_ptr(),
                t.as_ptr(),
                MAN.as_ptr().cast(),
                ptrs.as_ptr(),
                count,
                ptrs[default],
                &mut v,
                &mut set,
            )
        };
        if code != 0 {
            return Err(bad_value(name, &format!("give {}", one_of(choices))));
        }
        Ok(super::conv::to_usize(v))
    }

    /// Registers a string option with `default` shown by `-help`; whether it is given.
    fn string(&mut self, name: &str, text: &str, default: &str) -> Result<bool> {
        let (n, t) = Self::names(name, text)?;
        let d = cstring(default)?;
        let mut buf = vec![0 as c_char; 4096];
        let mut set = ffi::PetscBool_PETSC_FALSE;
        // SAFETY: a begun block; valid C strings; PETSc writes at most buf.len() bytes.
        chk!(PetscOptionsString_Private(
            &mut *self.items,
            n.as_ptr(),
            t.as_ptr(),
            MAN.as_ptr().cast(),
            d.as_ptr(),
            buf.as_mut_ptr(),
            buf.len(),
            &mut set
        ))?;
        Ok(set == ffi::PetscBool_PETSC_TRUE)
    }
}

/// `a, b or c`.
fn one_of(choices: &[&str]) -> String {
    match choices {
        [] => String::new(),
        [one] => (*one).to_string(),
        [rest @ .., last] => format!("{} or {last}", rest.join(", ")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn choices_read_as_a_list() {
        assert_eq!(one_of(&["pdas"]), "pdas");
        assert_eq!(one_of(&["zero", "last", "extrapolate"]), "zero, last or extrapolate");
        assert_eq!(key("-Step_Reuse"), "step_reuse");
    }
}
