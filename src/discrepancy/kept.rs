//! Built values kept for reuse within a budget, shared by threads. The analysis builds the
//! same corrections over and over (the joint refit chooses every correction again from its
//! whole family, round after round), and what it keeps it does not build again.

use std::collections::HashMap;
use std::hash::Hash;
use std::sync::Mutex;

/// Values by key, kept until their sizes add up to the budget; past it nothing more is kept.
/// A value is kept as it was built, so keeping it changes no figure. A poisoned lock (a
/// thread panicked mid-insert) only means that nothing more is found or kept: the analysis
/// goes on building without the store.
pub struct Kept<K, V> {
    budget: usize,
    inner: Mutex<Inner<K, V>>,
}

struct Inner<K, V> {
    values: HashMap<K, V>,
    /// The kept values' sizes, added up.
    held: usize,
}

impl<K: Hash + Eq, V: Clone> Kept<K, V> {
    /// An empty store that keeps values until their sizes add up to `budget`.
    pub fn new(budget: usize) -> Self {
        Kept {
            budget,
            inner: Mutex::new(Inner {
                values: HashMap::new(),
                held: 0,
            }),
        }
    }

    /// The value kept under `key`.
    pub fn get(&self, key: &K) -> Option<V> {
        self.inner.lock().ok()?.values.get(key).cloned()
    }

    /// Keeps `value` of `size` under `key`, unless that would pass the budget.
    pub fn keep(&self, key: K, value: &V, size: usize) {
        let Ok(mut inner) = self.inner.lock() else {
            return;
        };
        if inner.held + size > self.budget {
            return;
        }
        if inner.values.insert(key, value.clone()).is_none() {
            inner.held += size;
        }
    }

    /// How many values are kept.
    pub fn len(&self) -> usize {
        self.inner.lock().map_or(0, |inner| inner.values.len())
    }

    /// Whether nothing is kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values are kept until the budget is reached, and one that would pass it is not kept
    /// (nor counted); keeping a key again does not count it twice.
    #[test]
    fn values_are_kept_until_the_budget_is_reached() {
        let kept = Kept::new(10);
        kept.keep("a", &1, 6);
        kept.keep("a", &1, 6);
        kept.keep("b", &2, 5);
        kept.keep("c", &3, 4);
        assert_eq!(kept.get(&"a"), Some(1));
        assert_eq!(kept.get(&"b"), None);
        assert_eq!(kept.get(&"c"), Some(3));
        assert_eq!(kept.len(), 2);
    }
}
