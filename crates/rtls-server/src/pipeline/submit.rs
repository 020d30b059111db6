//! Records into the pipeline: payloads parsed and checked against the site, then appended
//! to the ingest log (or a cluster's stream) and acknowledged.

use rtls_engine::record::{parse_json_line, to_json_line, Record};
use tokio::sync::oneshot;

use super::fanout::PeerMessage;
use super::readers::ReaderMonitor;
use super::{partition_of, unix_ms, unix_s, IngestBatch, Pipeline};
use crate::sink::{IngestError, IngestFuture, IngestOrder, MeasurementSink, Turn};
use crate::store::NewRecord;

impl Pipeline {
    /// Parses a payload of JSON lines (`source` names it in errors, e.g. `http body`), checks
    /// every record against the site, and stores and queues them all (or none).
    ///
    /// # Errors
    /// [`IngestError::Invalid`] naming `source:line: field` for the first bad line;
    /// [`IngestError::Unavailable`] when the payload could not be stored.
    pub async fn submit_lines(&self, source: &str, payload: &[u8]) -> Result<usize, IngestError> {
        self.submit_lines_in_turn(source, payload, Turn::alone()).await
    }

    /// [`Pipeline::submit_lines`], queued after the payloads before `turn` in its sender's
    /// order (parsing and checking do not wait).
    async fn submit_lines_in_turn(&self, source: &str, payload: &[u8], turn: Turn) -> Result<usize, IngestError> {
        let text = std::str::from_utf8(payload).map_err(|e| {
            let line = 1 + payload[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count();
            IngestError::Invalid(format!("{source}:{line}: not UTF-8 text"))
        })?;
        let mut records = Vec::new();
        for (index, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            if records.len() == self.inner.config.max_records_per_payload {
                return Err(IngestError::Invalid(format!(
                    "{source}: more than {} records in one payload; split it",
                    self.inner.config.max_records_per_payload
                )));
            }
            let record = parse_json_line(line, source, index + 1).map_err(|e| self.refused("format", e.to_string()))?;
            records.push((index + 1, record));
        }
        self.submit_numbered(source, records, turn).await
    }

    /// Stores and queues records built elsewhere (the omlox location ingest); `source` names
    /// them in errors, with the 1-based index as the line.
    ///
    /// # Errors
    /// As [`Pipeline::submit_lines`].
    pub async fn submit_records(&self, source: &str, records: Vec<Record>) -> Result<usize, IngestError> {
        self.submit_records_in_turn(source, records, Turn::alone()).await
    }

    async fn submit_records_in_turn(
        &self,
        source: &str,
        records: Vec<Record>,
        turn: Turn,
    ) -> Result<usize, IngestError> {
        let numbered = records.into_iter().enumerate().map(|(i, r)| (i + 1, r)).collect();
        self.submit_numbered(source, numbered, turn).await
    }

    /// Checks, stores and queues the records; the queueing waits for `turn` (a cluster's
    /// stream is not ordered by it: its partitions re-filter a record that overtook another).
    async fn submit_numbered(
        &self,
        source: &str,
        records: Vec<(usize, Record)>,
        mut turn: Turn,
    ) -> Result<usize, IngestError> {
        if records.is_empty() {
            return Ok(0);
        }
        {
            let validator = self
                .inner
                .validator
                .lock()
                .map_err(|_| IngestError::Unavailable("the record validator failed".into()))?;
            for (line, record) in &records {
                validator
                    .check_record(record, source, *line)
                    .map_err(|e| self.refused("site", e.to_string()))?;
            }
        }
        if let Some(window) = self.inner.config.time_window.filter(|_| self.inner.config.live_clock) {
            let now_s = unix_s();
            for (line, record) in &records {
                if let Some(reason) = window.refusal(record.time_s, now_s) {
                    return Err(self.refused("time_window", format!("{source}:{line}: field `t`: {reason}")));
                }
            }
        }
        let received_ms = unix_ms();
        self.inner.readers.heard(records.iter().map(|(_, r)| r), received_ms);
        if let Some(cluster) = &self.inner.config.cluster {
            // every node's reader health counts the records any node received
            self.inner.fanout.to_peers(|| PeerMessage::ReadersHeard {
                counts: ReaderMonitor::counts(records.iter().map(|(_, r)| r)),
                at_ms: received_ms,
            });
            let partitions = self.inner.config.partitions.max(1);
            let lines = records
                .iter()
                .map(|(_, r)| (partition_of(&r.tag, partitions), to_json_line(r)))
                .collect();
            let started = std::time::Instant::now();
            let count = records.len();
            cluster.log.append(source, received_ms, lines).await?;
            self.inner
                .metrics
                .ingest_ack_seconds
                .observe(started.elapsed().as_secs_f64());
            return Ok(count);
        }
        let rows = records
            .iter()
            .map(|(_, r)| NewRecord {
                received_ms,
                source: source.to_string(),
                time_s: r.time_s,
                tag: r.tag.clone(),
                json: to_json_line(r),
            })
            .collect();
        let count = records.len();
        let (reply, answer) = oneshot::channel();
        let batch = IngestBatch {
            records: records.into_iter().map(|(_, r)| r).collect(),
            rows,
            reply,
            then: None,
        };
        let sender = self.ingest_sender()?;
        let started = std::time::Instant::now();
        let queued = async {
            turn.wait().await;
            sender.send(batch).await
        };
        let queued = tokio::time::timeout(self.inner.config.submit_timeout, queued).await;
        // queued or not, the sender's next payload may go
        turn.done();
        match queued {
            Ok(Ok(())) => {}
            Ok(Err(_)) => return Err(IngestError::Unavailable("the server is shutting down".into())),
            Err(_) => {
                self.inner.metrics.ingest_overloaded.inc();
                return Err(IngestError::Unavailable(format!(
                    "ingest queue full for {:?}; retry later",
                    self.inner.config.submit_timeout
                )));
            }
        }
        let result = answer
            .await
            .map_err(|_| IngestError::Unavailable("the ingest log stopped".into()))?;
        self.inner
            .metrics
            .ingest_ack_seconds
            .observe(started.elapsed().as_secs_f64());
        result.map(|_| count)
    }

    /// Parses a payload of a vendor's feed with its adapter ([`crate::adapters`]), counts each
    /// message without a position in `rtls_ingest_refused_total{reason}` (`no_position`,
    /// `anchor`; a malformed line among usable ones of a Zebra payload: `format`) and stores
    /// and queues the fixes as [`Pipeline::submit_records`] does.
    ///
    /// # Errors
    /// [`IngestError::Invalid`] naming `source: field` when the payload is malformed (counted
    /// with reason `format`; nothing of it is stored); otherwise as [`Pipeline::submit_records`].
    pub async fn submit_adapter(
        &self,
        vendor: crate::adapters::Vendor,
        source: &str,
        payload: &[u8],
    ) -> Result<AdapterOutcome, IngestError> {
        self.submit_adapter_in_turn(vendor, source, payload, Turn::alone())
            .await
    }

    /// [`Pipeline::submit_adapter`], queued in `turn`.
    async fn submit_adapter_in_turn(
        &self,
        vendor: crate::adapters::Vendor,
        source: &str,
        payload: &[u8],
        turn: Turn,
    ) -> Result<AdapterOutcome, IngestError> {
        let default_accuracy_m = self.inner.config.default_accuracy_m;
        let parsed = match (vendor, &self.inner.config.generic_adapter) {
            (crate::adapters::Vendor::Generic, Some(generic)) => generic.parse(payload, default_accuracy_m),
            (crate::adapters::Vendor::Zebra, _) => self.inner.config.zebra_adapter.parse(payload, default_accuracy_m),
            _ => crate::adapters::parse(vendor, payload, default_accuracy_m),
        }
        .map_err(|e| self.refused("format", format!("{source}: {e}")))?;
        for refusal in &parsed.refusals {
            self.inner
                .metrics
                .ingest_refused
                .get_or_create(&vec![("reason".into(), refusal.reason.into())])
                .inc();
            tracing::debug!(%source, at = %refusal.at, tag = ?refusal.tag, reason = refusal.reason,
                detail = %refusal.detail, "adapter: message without a position refused");
        }
        let accepted = self.submit_records_in_turn(source, parsed.records, turn).await?;
        Ok(AdapterOutcome {
            accepted,
            refusals: parsed.refusals,
        })
    }

    /// A payload refused for `reason` (`format`, `site`, `time_window`): counted in
    /// `rtls_ingest_refused_total{reason}` (nothing of the payload is stored).
    fn refused(&self, reason: &str, message: String) -> IngestError {
        self.inner
            .metrics
            .ingest_refused
            .get_or_create(&vec![("reason".into(), reason.into())])
            .inc();
        IngestError::Invalid(message)
    }
}

/// What [`Pipeline::submit_adapter`] did with a vendor payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AdapterOutcome {
    /// Fixes stored and queued.
    pub accepted: usize,
    /// Messages without a position (counted, not stored).
    pub refusals: Vec<crate::adapters::Refusal>,
}
impl MeasurementSink for Pipeline {
    /// JSON lines of our format, or — from an MQTT topic `rtls/v1/adapters/{vendor}/…` — a
    /// vendor's message through its adapter (refused messages are counted and logged).
    fn ingest(&self, source: &str, payload: bytes::Bytes, order: &mut IngestOrder) -> IngestFuture {
        let pipeline = self.clone();
        let source = source.to_string();
        let vendor = source
            .strip_prefix("mqtt:")
            .and_then(crate::adapters::Vendor::from_topic);
        let turn = order.next_turn();
        Box::pin(async move {
            match vendor {
                Some(vendor) => pipeline
                    .submit_adapter_in_turn(vendor, &source, &payload, turn)
                    .await
                    .map(|outcome| outcome.accepted),
                None => pipeline.submit_lines_in_turn(&source, &payload, turn).await,
            }
        })
    }
}
