//! Memory and time guard.

use super::*;

/// The case being run, for the watchdog to print.
pub(crate) static CURRENT_CASE: Mutex<String> = Mutex::new(String::new());
/// When the running case started (nanoseconds since [`epoch`], plus one; 0: none running).
pub(crate) static CASE_STARTED: AtomicU64 = AtomicU64::new(0);
/// The properties share the process's memory figures, so they take turns.
pub(crate) static SERIAL: Mutex<()> = Mutex::new(());

pub(crate) fn epoch() -> Instant {
    static E: OnceLock<Instant> = OnceLock::new();
    *E.get_or_init(Instant::now)
}

pub(crate) fn watchdog() {
    static START: Once = Once::new();
    START.call_once(|| {
        epoch();
        std::thread::spawn(|| {
            loop {
                std::thread::sleep(Duration::from_millis(50));
                let resident = status_bytes("VmRSS:");
                let why = if resident > HARD_MEMORY_LIMIT {
                    format!("holds {} MiB resident (limit {} MiB)", resident >> 20, HARD_MEMORY_LIMIT >> 20)
                } else {
                    match CASE_STARTED.load(Ordering::Relaxed) {
                        0 => continue,
                        t if epoch().elapsed().as_nanos() as u64 + 1 - t
                            > CASE_TIME_LIMIT.as_nanos() as u64 =>
                        {
                            format!("ran longer than {CASE_TIME_LIMIT:?}")
                        }
                        _ => continue,
                    }
                };
                let case = CURRENT_CASE.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone();
                eprintln!("gltf_fuzz: the loader {why}; that is a loader bug. The case:\n{case}");
                std::process::exit(101);
            }
        });
    });
}

/// Marks a case as running until dropped (also when the loader panics).
pub(crate) struct Running;

impl Running {
    pub(crate) fn start(case: &dyn Debug) -> Self {
        *CURRENT_CASE.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = format!("{case:#?}");
        CASE_STARTED.store(epoch().elapsed().as_nanos() as u64 + 1, Ordering::Relaxed);
        Self
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        CASE_STARTED.store(0, Ordering::Relaxed);
    }
}
