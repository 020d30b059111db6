//! `[cluster]`: `rtls serve --cluster` (docs/CLUSTER.md).

use std::time::Duration;

use serde::Deserialize;

/// `[cluster]`: how this node joins a cluster (`rtls serve --cluster` sets `servers`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClusterSection {
    /// NATS servers, `nats://host:port`; empty: no cluster (one process).
    pub servers: Vec<String>,
    /// This node's name in leases and logs; empty: `<hostname>-<pid>`.
    pub node_id: String,
    /// Tag partitions of the whole cluster (every node must use the same count).
    pub partitions: usize,
    /// Copies of the ingest stream and buckets (3 in a 3-server NATS cluster; 1 for one server).
    pub replicas: usize,
    /// A node not heard from for this long (s) is dead: its partitions are taken over. Nodes
    /// say they are alive on core NATS every quarter of it, which keeps working while
    /// JetStream elects leaders.
    pub failover_s: f64,
    /// How long a partition lease lives without renewal (s): the safety net when its owner
    /// cannot reach JetStream; longer than a JetStream leader election (4–9 s).
    pub lease_ttl_s: f64,
    /// How much of a partition's recent records its new owner tracks again (s), when it has
    /// no usable checkpoint.
    pub warmup_s: f64,
    /// How often an owner stores each partition's tracker state in the bucket
    /// `rtls_checkpoints` (s); 0: never (a new owner always warms up on `warmup_s`).
    pub checkpoint_s: f64,
    /// A checkpoint older than this (s) is not restored: the records after it would take
    /// too long to track again, and the new owner warms up on `warmup_s` instead.
    pub checkpoint_max_age_s: f64,
    /// How long the ingest stream keeps records (h).
    pub stream_max_age_h: f64,
}

impl Default for ClusterSection {
    fn default() -> Self {
        Self {
            servers: Vec::new(),
            node_id: String::new(),
            partitions: 12,
            replicas: 3,
            failover_s: 2.5,
            lease_ttl_s: 30.0,
            warmup_s: 30.0,
            checkpoint_s: 5.0,
            checkpoint_max_age_s: 300.0,
            stream_max_age_h: 24.0,
        }
    }
}

impl ClusterSection {
    /// Whether a cluster is configured.
    #[must_use]
    pub fn enabled(&self) -> bool {
        !self.servers.is_empty()
    }

    /// Checks the values.
    ///
    /// # Errors
    /// The key and why, as text.
    pub fn validate(&self) -> Result<(), String> {
        if let Some(bad) = self
            .servers
            .iter()
            .find(|s| !(s.starts_with("nats://") || s.starts_with("tls://")))
        {
            return Err(format!("[cluster] servers: `{bad}` is not a nats:// or tls:// URL"));
        }
        if self.partitions == 0 || self.partitions > 1024 {
            return Err(format!("[cluster] partitions = {}: must be 1..=1024", self.partitions));
        }
        if !(1..=5).contains(&self.replicas) {
            return Err(format!("[cluster] replicas = {}: must be 1..=5", self.replicas));
        }
        for (key, value, low) in [
            ("failover_s", self.failover_s, 0.5),
            ("lease_ttl_s", self.lease_ttl_s, 10.0),
            ("warmup_s", self.warmup_s, 0.0),
            ("checkpoint_s", self.checkpoint_s, 0.0),
            ("checkpoint_max_age_s", self.checkpoint_max_age_s, 0.0),
            ("stream_max_age_h", self.stream_max_age_h, 0.01),
        ] {
            if !(value.is_finite() && value >= low) {
                return Err(format!("[cluster] {key} = {value}: must be at least {low}"));
            }
        }
        if self.node_id.contains(['.', '*', '>', ' ']) {
            return Err(format!("[cluster] node_id `{}`: no dots, spaces, * or >", self.node_id));
        }
        Ok(())
    }

    /// The node's id: `node_id`, or `<hostname>-<pid>`.
    #[must_use]
    pub fn node_name(&self) -> String {
        if !self.node_id.is_empty() {
            return self.node_id.clone();
        }
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .map(|h| h.trim().replace(['.', ' '], "_"))
            .unwrap_or_else(|_| "node".into());
        format!("{host}-{}", std::process::id())
    }

    pub(crate) fn lease_ttl(&self) -> Duration {
        Duration::from_secs_f64(self.lease_ttl_s)
    }

    pub(crate) fn failover(&self) -> Duration {
        Duration::from_secs_f64(self.failover_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_settings_are_checked() {
        let good = ClusterSection {
            servers: vec!["nats://127.0.0.1:4222".into()],
            ..ClusterSection::default()
        };
        assert!(good.validate().is_ok());
        for bad in [
            ClusterSection {
                servers: vec!["127.0.0.1:4222".into()],
                ..good.clone()
            },
            ClusterSection {
                partitions: 0,
                ..good.clone()
            },
            ClusterSection {
                failover_s: 0.1,
                ..good.clone()
            },
            ClusterSection {
                node_id: "a.b".into(),
                ..good.clone()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
