//! Workspaces shared by the Python threads that call one object, without a lock held across a
//! call.
//!
//! A `Robot` or `FlexibleArm` may be called from several Python threads at once. Each call needs
//! a workspace of its own ([`crate::algorithms::Data`], [`crate::flex::ArmWorkspace`]). A mutex
//! held for the whole call deadlocks: while one thread holds it, numpy (or the garbage collector,
//! or any Python code) may release the GIL; another thread takes the GIL and waits for the mutex,
//! and the first can never take the GIL back. So the rule is: never wait for a Rust lock while
//! holding the GIL, and never hold one across a call into Python.
//!
//! A [`Pool`] lends each call a workspace of its own, which it owns until the call ends: no lock
//! is held while it computes or builds numpy arrays. The pool's lock guards only a `Vec` push or
//! pop, and is only ever *tried*: a busy pool lends a new workspace, and a workspace given back
//! to a busy pool is dropped. A call on one thread therefore never waits for another, and a
//! single thread (the common case) reuses one workspace and allocates nothing.

use std::ops::{Deref, DerefMut};
use std::sync::{Mutex, TryLockError};

/// Spare workspaces of type `T`, lent one per call ([`Pool::take`]).
pub(crate) struct Pool<T>(Mutex<Vec<T>>);

impl<T> Default for Pool<T> {
    fn default() -> Self {
        Self(Mutex::new(Vec::new()))
    }
}

impl<T> Pool<T> {
    /// A pool holding `first`.
    pub fn with(first: T) -> Self {
        Self(Mutex::new(vec![first]))
    }

    /// A workspace for one call: a spare one, or `make()` when none is free or another thread
    /// is pushing or popping at this instant. It returns to the pool when dropped.
    pub fn take(&self, make: impl FnOnce() -> T) -> Lent<'_, T> {
        let spare = match self.0.try_lock() {
            Ok(mut spares) => spares.pop(),
            // a panic while pushing or popping leaves the Vec valid
            Err(TryLockError::Poisoned(p)) => p.into_inner().pop(),
            Err(TryLockError::WouldBlock) => None,
        };
        Lent {
            pool: self,
            item: Some(spare.unwrap_or_else(make)),
        }
    }
}

/// A workspace lent by a [`Pool`], owned by its call; given back when dropped.
pub(crate) struct Lent<'a, T> {
    pool: &'a Pool<T>,
    item: Option<T>,
}

impl<T> Deref for Lent<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.item.as_ref().expect("lent until dropped")
    }
}

impl<T> DerefMut for Lent<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        self.item.as_mut().expect("lent until dropped")
    }
}

impl<T> Drop for Lent<'_, T> {
    fn drop(&mut self) {
        let item = self.item.take();
        match self.pool.0.try_lock() {
            Ok(mut spares) => spares.extend(item),
            Err(TryLockError::Poisoned(p)) => p.into_inner().extend(item),
            // busy: drop this one rather than wait (the pool keeps the others)
            Err(TryLockError::WouldBlock) => {}
        }
    }
}
