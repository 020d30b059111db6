//! Limits shared by the listeners (HTTP, MQTT): connections per IP address.

use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::{Arc, Mutex, PoisonError};

/// Connections per IP address (the MQTT broker's and the HTTP server's `max_connections_per_ip`).
#[derive(Debug, Default)]
pub struct IpSlots {
    held: Mutex<HashMap<IpAddr, usize>>,
}

impl IpSlots {
    /// One more connection of `ip`, held until the returned slot drops; `None` when `ip`
    /// already holds `limit`.
    ///
    /// # Examples
    /// ```
    /// use std::sync::Arc;
    /// use rtls_server::limits::IpSlots;
    ///
    /// let slots = Arc::new(IpSlots::default());
    /// let ip = "192.0.2.1".parse().unwrap();
    /// let held = slots.take(ip, 1).expect("the first");
    /// assert!(slots.take(ip, 1).is_none());
    /// drop(held);
    /// assert!(slots.take(ip, 1).is_some());
    /// ```
    #[must_use]
    pub fn take(self: &Arc<Self>, ip: IpAddr, limit: usize) -> Option<IpSlot> {
        let mut held = self.held.lock().unwrap_or_else(PoisonError::into_inner);
        let count = held.entry(ip).or_insert(0);
        if *count >= limit {
            return None;
        }
        *count += 1;
        Some(IpSlot {
            slots: Arc::clone(self),
            ip,
        })
    }
}

/// A connection counted against its IP address.
#[derive(Debug)]
pub struct IpSlot {
    slots: Arc<IpSlots>,
    ip: IpAddr,
}

impl Drop for IpSlot {
    fn drop(&mut self) {
        let mut held = self.slots.held.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(count) = held.get_mut(&self.ip) {
            *count -= 1;
            if *count == 0 {
                held.remove(&self.ip);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_ip_holds_at_most_its_limit_and_a_dropped_slot_is_free_again() {
        let slots = Arc::new(IpSlots::default());
        let ip: IpAddr = "192.0.2.7".parse().unwrap();
        let other: IpAddr = "192.0.2.8".parse().unwrap();
        let first = slots.take(ip, 2).expect("1 of 2");
        let _second = slots.take(ip, 2).expect("2 of 2");
        assert!(slots.take(ip, 2).is_none(), "a third is refused");
        assert!(slots.take(other, 2).is_some(), "another address is not");
        drop(first);
        assert!(slots.take(ip, 2).is_some(), "a freed slot is taken again");
    }
}
