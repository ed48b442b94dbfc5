//! A lock that a panicked holder does not make unusable.

use std::sync::{Mutex, MutexGuard};

/// Locks `mutex`, taking the data as it is if a holder panicked: every value kept here is
/// whole after each statement, so a poisoned lock holds nothing half-written.
pub(crate) fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}
