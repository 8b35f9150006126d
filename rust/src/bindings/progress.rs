//! A batch's progress, polled from Python while the workers fly.

use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// Progress of a batch, shared between the polling Python thread and the workers.
// `module`: the name the module gives its own classes (`_core`).
#[pyclass(frozen, module = "_core")]
pub(super) struct Progress {
    pub(super) done: Arc<AtomicU64>,
    pub(super) cancel: Arc<AtomicBool>,
}

#[pymethods]
impl Progress {
    #[new]
    fn new() -> Self {
        Self {
            done: Arc::new(AtomicU64::new(0)),
            cancel: Arc::new(AtomicBool::new(false)),
        }
    }
    /// Realisations finished so far.
    fn done(&self) -> u64 {
        self.done.load(Ordering::Relaxed)
    }
    /// Ask the workers to stop; finished realisations are kept.
    fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed)
    }
    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
}

/// The counters a batch updates: `progress`'s, or its own that no one polls.
pub(super) fn counters(
    progress: Option<&Bound<'_, Progress>>,
) -> (Arc<AtomicU64>, Arc<AtomicBool>) {
    match progress {
        Some(p) => (p.get().done.clone(), p.get().cancel.clone()),
        None => (
            Arc::new(AtomicU64::new(0)),
            Arc::new(AtomicBool::new(false)),
        ),
    }
}
