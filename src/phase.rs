//! Where a run is (its phase and step), the signals that stop it, and the watchdog that ends
//! a rank stuck in a collective operation.
//!
//! Every rank records here the phase it is in and the last step it finished. SIGINT and
//! SIGTERM only set a flag; the run polls it at every phase boundary and after every step
//! through [`stop_requested`], an allreduce, so all ranks stop at the same point and can close
//! the output file together (a signal that reaches one rank stops all of them).
//!
//! The watchdog is a thread per rank that watches the heartbeat the run gives at every phase
//! change and step. A rank that waits much longer than the run's median step (by default
//! `max(60 s, 1000 x median)`, armed once a few steps have been timed; `--hang-timeout`) is
//! waiting in a collective operation that will never complete: another rank died, stopped or
//! took a different path. The watchdog then prints the phase and step and aborts the MPI job
//! with exit code 3, instead of holding the allocation forever.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::error::{Error, Result};

/// The phases of a run, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Phase {
    Start = 0,
    Meshing,
    Partitioning,
    Assembling,
    SolverSetup,
    OpeningOutput,
    Stepping,
    /// After the last step: summary, pictures, the file's final attributes.
    Final,
    Finished,
}

impl Phase {
    const ALL: [Phase; 9] = [
        Phase::Start,
        Phase::Meshing,
        Phase::Partitioning,
        Phase::Assembling,
        Phase::SolverSetup,
        Phase::OpeningOutput,
        Phase::Stepping,
        Phase::Final,
        Phase::Finished,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Phase::Start => "start-up",
            Phase::Meshing => "meshing",
            Phase::Partitioning => "partitioning",
            Phase::Assembling => "assembly",
            Phase::SolverSetup => "solver setup",
            Phase::OpeningOutput => "opening the output",
            Phase::Stepping => "stepping",
            Phase::Final => "the final phase",
            Phase::Finished => "finishing",
        }
    }
}

static PHASE: AtomicU8 = AtomicU8::new(0);
/// Steps finished so far (the step the run is at).
static STEP: AtomicU64 = AtomicU64::new(0);
/// Milliseconds since `epoch()` of the last heartbeat.
static BEAT_MS: AtomicU64 = AtomicU64::new(0);
/// Watchdog timeout in milliseconds; 0 = disarmed.
static TIMEOUT_MS: AtomicU64 = AtomicU64::new(0);
static SIGNAL: AtomicBool = AtomicBool::new(false);

fn epoch() -> Instant {
    static EPOCH: OnceLock<Instant> = OnceLock::new();
    *EPOCH.get_or_init(Instant::now)
}

fn now_ms() -> u64 {
    epoch().elapsed().as_millis() as u64
}

/// The heartbeat: the run made progress now.
pub fn beat() {
    BEAT_MS.store(now_ms(), Ordering::SeqCst);
}

/// Enter a phase (and give a heartbeat).
pub fn enter(phase: Phase) {
    PHASE.store(phase as u8, Ordering::SeqCst);
    release_free_memory();
    trace_memory(phase.name());
    beat();
}

/// Returns the heap's free pages to the system (glibc's `malloc_trim`). The set-up phases
/// free large temporaries (the mesh's exchange buffers, the summed rows); kept by the
/// allocator, they fragment the heap and the next phase's matrices land beside them, so the
/// resident memory grows by what was freed (measured: 4 ranks at 10^6 DOFs, 452 MiB per
/// rank against 409 with the trim). A few milliseconds per phase change.
pub fn release_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        extern "C" {
            fn malloc_trim(pad: usize) -> i32;
        }
        // SAFETY: glibc's malloc_trim only returns free heap pages to the system.
        unsafe { malloc_trim(0) };
    }
}

/// With `MASSFREE_TRACE_MEMORY` set, every rank prints its resident and peak memory at each
/// phase boundary and after the first steps (for measuring what a run's peak is made of).
pub fn trace_memory(at: &str) {
    static ON: OnceLock<bool> = OnceLock::new();
    if !*ON.get_or_init(|| std::env::var_os("MASSFREE_TRACE_MEMORY").is_some()) {
        return;
    }
    static T0: OnceLock<Instant> = OnceLock::new();
    eprintln!(
        "memory [pid {}] at {at} ({:.2} s): resident {:.0} MiB, peak {:.0} MiB",
        std::process::id(),
        T0.get_or_init(Instant::now).elapsed().as_secs_f64(),
        status_mib("VmRSS:"),
        status_mib("VmHWM:")
    );
}

/// A memory field of `/proc/self/status` (`"VmRSS:"` resident, `"VmHWM:"` peak resident) in
/// MiB; 0 where /proc is unavailable.
pub fn status_mib(name: &str) -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix(name))
                .and_then(|v| v.split_whitespace().next()?.parse::<f64>().ok())
        })
        .map_or(0.0, |kib| kib / 1024.0)
}

/// The phase this rank is in.
pub fn current() -> Phase {
    Phase::ALL[PHASE.load(Ordering::SeqCst) as usize]
}

/// Record that step `n` is finished (and give a heartbeat).
pub fn step_done(n: usize) {
    STEP.store(n as u64, Ordering::SeqCst);
    if n <= 2 {
        trace_memory(&format!("step {n}"));
    }
    beat();
}

/// The last finished step.
pub fn step() -> usize {
    STEP.load(Ordering::SeqCst) as usize
}

/// "stepping after step 120", "assembly", ... for messages.
pub fn describe() -> String {
    match current() {
        p @ (Phase::Stepping | Phase::Final | Phase::Finished) => {
            format!("{} after step {}", p.name(), step())
        }
        p => p.name().to_string(),
    }
}

/// Route SIGINT and SIGTERM to the flag polled by [`signalled`] and [`stop_requested`]. Call
/// it first thing, before MPI starts its threads.
///
/// The two signals are blocked in this thread and so in every thread created after it (MPI's,
/// PETSc's, the watchdog: they inherit the mask), and one thread takes them with `sigwait`.
/// No handler runs, so a signal can never cut into a library call: METIS (GKlib) installs its
/// own SIGTERM handler that jumps out of the partitioner, and a SIGTERM during partitioning
/// made the run fail with "METIS returned an error" before. (Child processes such as gmsh
/// start with an empty mask.)
pub fn install_signal_handlers() -> Result<()> {
    use nix::sys::signal::{SigSet, Signal};
    let set: SigSet = [Signal::SIGINT, Signal::SIGTERM].into_iter().collect();
    set.thread_block().map_err(|e| Error::Usage(format!("cannot block SIGINT/SIGTERM: {e}")))?;
    std::thread::Builder::new()
        .name("massfree-signals".into())
        .spawn(move || loop {
            if set.wait().is_ok() {
                SIGNAL.store(true, Ordering::SeqCst);
            }
        })
        .map_err(|e| Error::Usage(format!("cannot start the signal thread: {e}")))?;
    Ok(())
}

/// Whether this rank received SIGINT or SIGTERM (local, no communication).
pub fn signalled() -> bool {
    SIGNAL.load(Ordering::SeqCst)
}

/// Whether any rank received a signal. Collective: every rank must call it at the same point.
pub fn stop_requested(world: &impl Communicator) -> bool {
    let mine = i32::from(signalled());
    let mut any = 0i32;
    world.all_reduce_into(&mine, &mut any, SystemOperation::max());
    any > 0
}

/// `Err(Interrupted)` naming the phase if any rank received a signal. Collective.
pub fn check_signal(world: &impl Communicator) -> Result<()> {
    if stop_requested(world) {
        return Err(interrupted());
    }
    Ok(())
}

/// The error of a run stopped by a signal in the current phase.
pub fn interrupted() -> Error {
    Error::Interrupted(format!("a signal stopped the run during {}", describe()))
}

/// How long a rank may wait without progress before the watchdog aborts the job.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HangTimeout {
    /// `max(60 s, 1000 x median step time)`, armed after the first timed steps.
    Auto,
    Off,
    /// A fixed number of seconds, armed from the first step on.
    Seconds(f64),
}

impl HangTimeout {
    /// `auto`, `off` or a number of seconds.
    pub fn parse(s: &str) -> std::result::Result<HangTimeout, String> {
        match s {
            "auto" => Ok(HangTimeout::Auto),
            "off" => Ok(HangTimeout::Off),
            _ => match s.parse::<f64>() {
                Ok(x) if x > 0.0 && x.is_finite() => Ok(HangTimeout::Seconds(x)),
                _ => {
                    Err(format!("expected auto, off or a positive number of seconds, found {s:?}"))
                }
            },
        }
    }
}

/// Steps timed before the automatic timeout is armed, and the window of the median.
const AUTO_MIN_STEPS: usize = 5;
const WINDOW: usize = 255;

/// The rank's watchdog: feed it step times; its thread aborts the job on a hang.
pub struct Watchdog {
    policy: HangTimeout,
    /// The last step times (a ring of `WINDOW`), for the median.
    recent: Vec<f64>,
    next: usize,
    timed: usize,
}

impl Watchdog {
    /// Start the watchdog thread of this rank (none for `Off`). The thread lives until the
    /// process ends; it is idle while disarmed.
    pub fn start(policy: HangTimeout, rank: usize) -> Watchdog {
        static STARTED: AtomicBool = AtomicBool::new(false);
        if policy != HangTimeout::Off && !STARTED.swap(true, Ordering::SeqCst) {
            beat();
            std::thread::Builder::new()
                .name("massfree-watchdog".into())
                .spawn(move || watch(rank))
                .ok();
        }
        Watchdog { policy, recent: Vec::with_capacity(WINDOW), next: 0, timed: 0 }
    }

    /// Arm the watchdog for the time loop (fixed timeouts start here).
    pub fn arm(&mut self) {
        if let HangTimeout::Seconds(s) = self.policy {
            TIMEOUT_MS.store((s * 1e3).ceil() as u64, Ordering::SeqCst);
        }
        beat();
    }

    /// Feed the wall time of one step; the automatic timeout follows the median.
    pub fn step_time(&mut self, seconds: f64) {
        if self.policy != HangTimeout::Auto {
            return;
        }
        if self.recent.len() < WINDOW {
            self.recent.push(seconds);
        } else {
            self.recent[self.next] = seconds;
        }
        self.next = (self.next + 1) % WINDOW;
        self.timed += 1;
        // Recomputed now and then: a median of 255 numbers is cheap but not free per step.
        if self.timed >= AUTO_MIN_STEPS && (self.timed == AUTO_MIN_STEPS || self.timed % 64 == 0) {
            let mut v = self.recent.clone();
            v.sort_by(f64::total_cmp);
            let median = v[v.len() / 2];
            let timeout = (1000.0 * median).max(60.0);
            TIMEOUT_MS.store((timeout * 1e3).ceil() as u64, Ordering::SeqCst);
        }
    }

    /// Disarm (the run is over; nothing collective follows that could hang unseen).
    pub fn disarm(&self) {
        TIMEOUT_MS.store(0, Ordering::SeqCst);
    }
}

fn watch(rank: usize) {
    loop {
        std::thread::sleep(Duration::from_millis(200));
        let timeout = TIMEOUT_MS.load(Ordering::SeqCst);
        if timeout == 0 {
            continue;
        }
        let idle = now_ms().saturating_sub(BEAT_MS.load(Ordering::SeqCst));
        if idle > timeout {
            eprintln!(
                "massfree: rank {rank} made no progress for {:.0} s in {}: a collective operation hung (another rank died, stopped or took a different path); aborting the run",
                idle as f64 / 1e3,
                describe()
            );
            // MPI_Abort ends every rank of the job, including those stuck elsewhere.
            mpi::topology::SimpleCommunicator::world().abort(3);
        }
    }
}

/// Whether every rank reached this call within `timeout`: true when an error happened on all
/// ranks alike (they can then close the output together), false when only some ranks failed
/// (the others are elsewhere, and nothing collective may be attempted). `comm` must be a
/// communicator used for nothing else (a duplicate of the world), so that a barrier posted by
/// some ranks only cannot be matched with another collective.
pub fn all_reached(comm: &impl Communicator, timeout: Duration) -> bool {
    if comm.size() == 1 {
        return true;
    }
    let mut req = comm.immediate_barrier();
    let t0 = Instant::now();
    loop {
        match req.test() {
            Ok(_) => return true,
            Err(r) => req = r,
        }
        if t0.elapsed() > timeout {
            // The request cannot be cancelled; the caller aborts the job next.
            std::mem::forget(req);
            return false;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}
