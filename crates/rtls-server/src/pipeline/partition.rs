//! A partition thread: one tracker for the tags hashed to it; publishes what it produces.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rtls_engine::lifecycle::TrackStatus;
use rtls_engine::record::Record;
use rtls_engine::site::Site;
use rtls_engine::tracker::{status_name, AnchorOffsetSummary, Event, Output, TrackUpdate, Tracker};
use rtls_engine::zones::{ZoneEvent, ZoneKind};
use serde_json::Value;

use super::fanout::Fanout;
use super::ingest_log::PartitionInput;
use super::live::{HubMessage, TagState};
use super::outputs::OutputBatch;
use super::quarantine::{guarded, Quarantined};
use super::{unix_ms, unix_s, Progress};
use crate::convert::{
    accuracy_m, alarm_id, extension_payload, fence_event_from_zone_event, is_alarm, location_from_update, ZoneEventOut,
};
use crate::metrics::Metrics;
use crate::omlox::ProviderType;
use crate::sink::Publication;
use crate::store::{EventRow, LocationRow};

/// How often an idle partition advances its tracker with the wall clock, and how long it must
/// have been without records to count as idle.
const CLOCK_TICK: Duration = Duration::from_millis(250);

pub(super) struct PartitionWorker {
    pub index: usize,
    /// When the offsets were last posted, and whether a batch has come since.
    pub offsets_posted: Option<Instant>,
    pub offsets_dirty: bool,
    pub tracker: Tracker,
    pub rx: Receiver<PartitionInput>,
    pub outputs: SyncSender<OutputBatch>,
    /// The live state and broadcasts (and, in a cluster, the peers).
    pub fanout: Fanout,
    /// The site, for a fresh tracker when the partition is reset.
    pub site: Arc<Site>,
    pub metrics: Arc<Metrics>,
    pub progress: Arc<Progress>,
    pub live_clock: bool,
    /// How far behind the wall clock the live clock runs ([`super::clock_lag`]).
    pub clock_lag: super::clock_lag::LiveClockLag,
    /// The newest record taken, which caps the live clock ([`super::event_clock`]).
    pub event_clock: super::event_clock::EventClock,
    /// The slowest active sender's position in record time, which holds the tracker's ticks
    /// ([`super::watermark`]).
    pub watermark: super::watermark::Watermark,
    /// Which track states are stored (`server.history_interval_s`).
    pub history: super::history_rate::HistoryRate,
    /// Entry time (s) of each (tag, zone) the tag is in, for the exit's `entry_time`.
    pub zone_entries: HashMap<(String, String), f64>,
    /// Tags whose lost state (the frozen last position) has been stored and published once:
    /// the tracker repeats it every output interval until the track is deleted, which would
    /// cost a row per silent tag per interval and say nothing new.
    pub reported_lost: HashSet<String>,
    /// The omlox `source` of our locations (the site's name).
    pub source: String,
    /// The version of the live zone set the tracker holds.
    pub zones_version: u64,
    /// The site's and build's fingerprint, which a checkpoint must carry to be restored.
    pub site_fingerprint: u64,
    /// One record into the tracker ([`super::TrackStep`]).
    pub track_step: super::TrackStep,
    /// Events of the partition's own (quarantined records) waiting for the next batch.
    pub pending_events: Vec<EventRow>,
    /// How often an unused record is logged ([`crate::log_limit::LOG_PERIOD`]).
    pub unused_log: crate::log_limit::LogLimiter,
    /// How often a wait for the store is logged.
    pub store_wait_log: crate::log_limit::LogLimiter,
}

impl PartitionWorker {
    pub fn run(mut self) {
        let mut out = Output::default();
        let mut last_clock = Instant::now();
        // whether the partition has caught up with its input: the wall clock moves a tracker
        // only then. While batches keep coming their records move it (event time); a clock
        // run ahead of a backlog would make each queued record older than ticks its track
        // was given, so every one would rewind and re-filter (the cost grows with the backlog
        // it causes) or, without a rewind horizon, be reported late
        let mut caught_up;
        loop {
            let mut processed = None;
            let mut quarantined = Vec::new();
            self.progress.beat(self.index);
            self.follow_zone_edits();
            match self.rx.recv_timeout(CLOCK_TICK) {
                Ok(PartitionInput::Records(batch)) => {
                    caught_up = false;
                    // an edit made while this batch waited applies to it
                    self.follow_zone_edits();
                    let started = Instant::now();
                    let (oldest_s, newest_s) = batch.iter().fold(
                        (f64::INFINITY, f64::NEG_INFINITY),
                        |(oldest_s, newest_s), (_, record)| (oldest_s.min(record.time_s), newest_s.max(record.time_s)),
                    );
                    // the batch's arrival, for the live clock's lag and the watermark
                    let wall_s = unix_s();
                    self.event_clock.observe(newest_s);
                    self.clock_lag.observe(oldest_s, wall_s);
                    self.hold_ticks(&batch, newest_s, wall_s);
                    for (id, record) in batch {
                        let tag = record.tag.clone();
                        let (tracker, step) = (&mut self.tracker, self.track_step);
                        if let Err(reason) = guarded(|| step(tracker, record, &mut out)) {
                            self.quarantine(id, tag, reason, &mut quarantined);
                        }
                        processed = Some(id);
                    }
                    // each update leaves with the batch that produced it, not with the tag's
                    // next record (a later record of the same time is a flagged revision)
                    if let Err(e) = self.tracker.report_pending(&mut out) {
                        tracing::warn!(partition = self.index, error = %e, "reporting the batch's updates failed");
                    }
                    self.metrics.tracking_seconds.observe(started.elapsed().as_secs_f64());
                    self.offsets_dirty = true;
                }
                Ok(PartitionInput::WarmUp(records)) => {
                    self.warm_up(records, &mut out);
                    continue;
                }
                Ok(PartitionInput::Reset) => {
                    self.reset(&mut out);
                    continue;
                }
                Ok(PartitionInput::Checkpoint(reply)) => {
                    let _ = reply.send(self.checkpoint());
                    continue;
                }
                Ok(PartitionInput::Restore(bytes, reply)) => {
                    let _ = reply.send(self.restore(&bytes, &mut out));
                    continue;
                }
                Err(RecvTimeoutError::Timeout) => caught_up = true,
                Err(RecvTimeoutError::Disconnected) => {
                    if let Err(e) = self.tracker.finish(&mut out) {
                        tracing::warn!(partition = self.index, error = %e, "flushing the tracker failed");
                    }
                    self.emit(&mut out, None, Vec::new());
                    return;
                }
            }
            if self.live_clock && caught_up && last_clock.elapsed() >= CLOCK_TICK {
                last_clock = Instant::now();
                let wall_s = unix_s();
                let lag_s = self.clock_lag.lag_s(wall_s);
                self.metrics.live_clock_lag_seconds.observe(lag_s);
                let target_s = self.event_clock.target_s(wall_s, lag_s);
                self.hold_ticks(&[], f64::NEG_INFINITY, wall_s);
                if let Err(e) = self.tracker.advance_to(target_s, &mut out) {
                    tracing::warn!(partition = self.index, error = %e, "advancing the clock failed");
                }
            }
            self.post_offsets();
            self.emit(&mut out, processed, quarantined);
        }
    }

    /// Notes the batch's arrivals and sets the tracker's watermark from them
    /// ([`super::watermark`]): the ticks wait for the slowest sender still heard, so its tags
    /// are not coasted and then rewound by the other senders' newer records. `newest_s`: the
    /// batch's newest record time (−∞ for none); `wall_s`: the Unix time of its arrival. The lag it holds the ticks by is observed in
    /// `rtls_watermark_lag_seconds`. Nothing is done without a rewind horizon (the tracker
    /// ignores a watermark then).
    fn hold_ticks(&mut self, batch: &[(i64, Record)], newest_s: f64, wall_s: f64) {
        let horizon_s = self.site.tracker.rewind_horizon_s;
        if horizon_s <= 0.0 {
            return;
        }
        let now = Instant::now();
        for (_, record) in batch {
            self.watermark.observe(&record.tag, record.time_s, wall_s, now);
        }
        let watermark_s = self.watermark.watermark_s(wall_s, now, horizon_s);
        if let Some(watermark_s) = watermark_s.filter(|_| newest_s.is_finite()) {
            // ticks are held by at most the horizon (the tracker's floor)
            let lag_s = (newest_s - watermark_s).clamp(0.0, horizon_s);
            self.metrics.watermark_lag_seconds.observe(lag_s);
        }
        self.tracker.set_watermark(watermark_s);
    }

    /// Records a peer already tracked and stored (cluster takeover): they rebuild the tracks'
    /// state, and what the tracker produces from them is not published or stored again. A
    /// record the tracker refuses here was reported by the node that tracked it first.
    fn warm_up(&mut self, records: Vec<Record>, out: &mut Output) {
        self.follow_zone_edits();
        let count = records.len();
        let newest_s = records
            .iter()
            .map(|record| record.time_s)
            .fold(f64::NEG_INFINITY, f64::max);
        self.event_clock.observe(newest_s);
        for record in records {
            let (tracker, step) = (&mut self.tracker, self.track_step);
            let _ = guarded(|| step(tracker, record, out));
        }
        let _ = self.tracker.report_pending(out);
        out.clear();
        // the zone entries the warm-up passed are this partition's from now on
        self.publish_occupants();
        tracing::info!(
            partition = self.index,
            records = count,
            "partition warmed up from the ingest stream"
        );
    }

    /// Forgets every track (the partition moved to another node of the cluster): nothing is
    /// published for them here any more; the new owner publishes from its warm-up on.
    fn reset(&mut self, out: &mut Output) {
        match Tracker::new(&self.site) {
            Ok(tracker) => self.tracker = tracker,
            Err(e) => tracing::error!(partition = self.index, error = %e, "a fresh tracker failed; the old one stays"),
        }
        out.clear();
        self.pending_events.clear();
        self.zone_entries.clear();
        self.reported_lost.clear();
        self.history.clear();
        // the fresh tracker has the site's zones: hand it the live set at once
        self.zones_version = u64::MAX;
        self.follow_zone_edits();
    }

    /// Posts the tracker's learnt range offsets to the reader health, at most once per
    /// [`super::readers::OFFSET_PUBLISH_PERIOD`] and only after new records.
    fn post_offsets(&mut self) {
        let due = self
            .offsets_posted
            .is_none_or(|at| at.elapsed() >= super::readers::OFFSET_PUBLISH_PERIOD);
        if self.offsets_dirty && due {
            let summaries = AnchorOffsetSummary::by_anchor(&self.tracker.range_offsets());
            self.fanout.post_offsets(self.index, summaries);
            self.offsets_posted = Some(Instant::now());
            self.offsets_dirty = false;
        }
    }

    /// A record the tracker did not use (`rejected`, `late`): counted by event and
    /// measurement kind in `rtls_records_unused_total{event, kind}`, and logged — at most once
    /// every [`crate::log_limit::LOG_PERIOD`] per partition, with how many went unlogged since.
    fn note_unused(&mut self, event: &str, parsed: &Value) {
        let kind = parsed["kind"].as_str().unwrap_or("unknown");
        self.metrics
            .records_unused
            .get_or_create(&vec![("event".into(), event.into()), ("kind".into(), kind.into())])
            .inc();
        if let Some(records) = self.unused_log.occurred() {
            tracing::warn!(
                partition = self.index,
                event,
                kind,
                tag = parsed["tag"].as_str().unwrap_or(""),
                reason = unused_reason(parsed).as_str(),
                records,
                "record not used (the count is since the last such line; every one is an event)"
            );
        }
    }

    /// A record the tracker failed on (an error or a panic): counted, logged, published as a
    /// `record-quarantined` event, and handed to the output thread to be stored apart.
    fn quarantine(&mut self, record_id: i64, tag: String, reason: String, quarantined: &mut Vec<Quarantined>) {
        self.metrics.tracker_errors.inc();
        self.metrics.records_quarantined.inc();
        tracing::error!(partition = self.index, record_id, tag = %tag, reason = %reason, "record quarantined");
        let event = serde_json::json!({
            "type": "record-quarantined",
            "t": unix_s(),
            "tag": tag,
            "record_id": record_id,
            "partition": self.index,
            "reason": reason,
        });
        let json = event.to_string();
        self.fanout.publish(Publication {
            topic: "rtls/v1/events/record-quarantined".into(),
            payload: json.clone().into(),
        });
        quarantined.push(Quarantined {
            record_id,
            partition: self.index,
            tag,
            reason,
            quarantined_ms: unix_ms(),
        });
        self.pending_events.push(EventRow {
            received_ms: unix_ms(),
            time_s: unix_s(),
            kind: "record-quarantined".into(),
            tag: event["tag"].as_str().map(str::to_string),
            zone: None,
            alarm: false,
            json,
        });
    }

    /// Publishes and queues for storage what the tracker produced; `processed` is the last
    /// ingest-log id whose record it has taken.
    fn emit(&mut self, out: &mut Output, processed: Option<i64>, quarantined: Vec<Quarantined>) {
        if out.updates.is_empty() && out.events.is_empty() && processed.is_none() && quarantined.is_empty() {
            return;
        }
        let received_ms = unix_ms();
        let mut batch = OutputBatch {
            partition: self.index,
            processed_id: processed,
            locations: Vec::with_capacity(out.updates.len()),
            events: std::mem::take(&mut self.pending_events),
            quarantined,
        };
        for update in &out.updates {
            self.publish_update(update, received_ms, &mut batch);
        }
        for event in &out.events {
            self.publish_event(event, received_ms, &mut batch);
        }
        if !out.events.is_empty() {
            self.publish_occupants();
        }
        out.clear();
        let batch = match self.outputs.try_send(batch) {
            Ok(()) => return,
            Err(TrySendError::Full(batch)) => {
                // the store cannot keep up: tracking waits for it, and back-pressure reaches
                // the senders; say so, and what helps
                self.metrics.output_store_waits.inc();
                if let Some(waits) = self.store_wait_log.occurred() {
                    tracing::warn!(
                        partition = self.index,
                        waits,
                        "the store cannot keep up with the track states and events (output queue full; \
                         the count is since the last such line): ingest is held back. \
                         server.history_interval_s stores fewer states"
                    );
                }
                batch
            }
            Err(TrySendError::Disconnected(batch)) => batch,
        };
        if self.outputs.send(batch).is_err() {
            tracing::error!(partition = self.index, "output thread stopped; outputs not stored");
            if let Some(id) = processed {
                self.progress.stored[self.index].fetch_max(id, Ordering::AcqRel);
            }
        }
    }

    /// Hands a zone edit (the control room's zone editor) to the tracker.
    fn follow_zone_edits(&mut self) {
        let version = self.fanout.live.zones_version();
        if version == self.zones_version {
            return;
        }
        self.zones_version = version;
        match self.tracker.replace_zones(self.fanout.live.zones().to_vec()) {
            Ok(()) => self.publish_occupants(),
            // the API validated the set; a failure here is a bug, and the old zones stay
            Err(e) => tracing::error!(partition = self.index, error = %e, "the edited zones were refused"),
        }
    }

    pub(super) fn publish_occupants(&self) {
        let occupants = self
            .fanout
            .live
            .zones()
            .iter()
            .map(|zone| {
                let tags = self.tracker.occupants(&zone.id).into_iter().map(String::from).collect();
                (zone.id.clone(), tags)
            })
            .collect();
        self.fanout.set_occupants(self.index, occupants);
    }

    fn publish_update(&mut self, update: &TrackUpdate, received_ms: i64, batch: &mut OutputBatch) {
        // a lost track's frozen position: stored and published once, not every interval
        if update.status == TrackStatus::Lost {
            if self.reported_lost.contains(&*update.tag) {
                return;
            }
            self.reported_lost.insert(update.tag.to_string());
        } else if !self.reported_lost.is_empty() {
            self.reported_lost.remove(&*update.tag);
        }
        self.metrics.track_updates.inc();
        if update.revised {
            self.metrics.track_updates_revised.inc();
        }
        let json_line = update.to_json_line();
        let d = update.dimensions.clamp(2, 3);
        let stored = self.history.keep(
            &update.tag,
            super::history_rate::StateKind {
                time_s: update.time_s,
                status: update.status,
                predicted: update.predicted,
                revised: update.revised,
            },
        );
        if update.status == TrackStatus::Deleted {
            self.history.forget(&update.tag);
        }
        if stored {
            batch.locations.push(LocationRow {
                received_ms,
                time_s: update.time_s,
                tag: update.tag.to_string(),
                x_m: update.position_m[0],
                y_m: update.position_m[1],
                z_m: (d == 3).then_some(update.position_m[2]),
                accuracy_m: Some(accuracy_m(&update.position_covariance_m2, d)),
                predicted: update.predicted,
                json: json_line.clone(),
            });
        }
        self.fanout.publish(Publication {
            topic: format!("rtls/v1/tracks/{}", mqtt_level(&update.tag)),
            payload: json_line.into(),
        });
        if update.status == TrackStatus::Deleted {
            self.fanout.remove_tag(&update.tag);
            return;
        }
        match location_from_update(update, &self.source, ProviderType::Uwb) {
            Ok(mut location) => {
                // omlox's course is from true north
                location.course = location
                    .course
                    .map(|course| crate::convert::true_course_deg(course, self.site.frame.as_ref()));
                // a provider that pushes its own locations keeps what it said
                let location = match self.fanout.live.pushed(&update.tag, update.time_s) {
                    Some(pushed) => crate::pushed::with_pushed(location, &pushed, update.time_s),
                    None => location,
                };
                let location = Arc::new(location);
                self.fanout.set_tag(
                    &update.tag,
                    TagState {
                        time_s: update.time_s,
                        position_m: update.position_m,
                        status: status_name(update.status),
                        location: Arc::clone(&location),
                    },
                );
                self.fanout.hub(HubMessage::Location {
                    tag: update.tag.to_string(),
                    time_s: update.time_s,
                    location,
                });
                self.metrics
                    .pipeline_latency_seconds
                    .observe((unix_s() - update.time_s).max(0.0));
            }
            Err(e) => tracing::warn!(tag = %update.tag, error = %e, "location not representable"),
        }
    }

    fn publish_event(&mut self, event: &Event, received_ms: i64, batch: &mut OutputBatch) {
        let mut json_line = event.to_json_line();
        let mut parsed: Value = serde_json::from_str(&json_line).unwrap_or(Value::Null);
        let kind = parsed["type"].as_str().unwrap_or("event").to_string();
        let tag = parsed["tag"].as_str().map(str::to_string);
        let zone = parsed["zone"].as_str().map(str::to_string);
        // entering a hazard or restricted zone is an alarm too (the fence event says the same
        // to omlox clients; the control room must see it in its console)
        if kind == "rejected" || kind == "late" {
            self.note_unused(&kind, &parsed);
        }
        let entered_kind = self.entered_guarded_zone(event);
        let alarm = is_alarm(event) || entered_kind.is_some();
        if alarm {
            // a stable id: the same event (replayed after a restart, too) has the same id
            if let Value::Object(object) = &mut parsed {
                object.insert("alarm_id".into(), Value::String(alarm_id(&json_line)));
                if let Some(kind) = entered_kind {
                    object.insert("zone_kind".into(), Value::String(kind.into()));
                }
                json_line = parsed.to_string();
            }
            self.fanout.note_alarm(&parsed);
            self.metrics
                .alarms
                // a lost tag is counted as `lost`, not as its event type `lifecycle`
                .get_or_create(&vec![(
                    "type".into(),
                    parsed["event"].as_str().unwrap_or(&kind).to_string(),
                )])
                .inc();
        }
        batch.events.push(EventRow {
            received_ms,
            time_s: event.time_s(),
            kind: kind.clone(),
            tag,
            zone,
            alarm,
            json: json_line.clone(),
        });
        self.fanout.publish(Publication {
            topic: format!("rtls/v1/events/{kind}"),
            payload: json_line.into(),
        });
        let parsed_alarm = entered_kind.map(|_| parsed.clone());
        let message = match event {
            Event::Zone(zone_event) => {
                let entry = self.track_zone_entry(zone_event);
                match fence_event_from_zone_event(zone_event, entry) {
                    Ok(ZoneEventOut::Fence(mut fence_event)) => {
                        // omlox: "the ids of trackables the provider is assigned to"
                        let assigned = self.fanout.live.trackables().assigned(zone_event.tag());
                        fence_event.trackables = (!assigned.is_empty()).then_some(assigned);
                        serde_json::to_value(fence_event)
                            .ok()
                            .map(|event| HubMessage::FenceEvent {
                                tag: zone_event.tag().to_string(),
                                event,
                            })
                    }
                    Ok(ZoneEventOut::Extension(topic, event)) => Some(HubMessage::Extension { topic, event }),
                    Err(e) => {
                        tracing::warn!(error = %e, "zone event not representable");
                        None
                    }
                }
            }
            other => match extension_payload(other, parsed) {
                Ok((topic, event)) => Some(HubMessage::Extension { topic, event }),
                Err(e) => {
                    tracing::warn!(error = %e, "event not representable");
                    None
                }
            },
        };
        if let Some(message) = message {
            self.fanout.hub(message);
        }
        if let Some(event) = parsed_alarm {
            self.fanout.hub(HubMessage::Extension {
                topic: crate::omlox::ws::Topic::RtlsAlarms,
                event,
            });
        }
    }

    /// The kind (`hazard`, `restricted`) of the zone an entry event enters, when it is one the
    /// control room is alarmed about.
    fn entered_guarded_zone(&self, event: &Event) -> Option<&'static str> {
        let Event::Zone(ZoneEvent::Enter { zone, .. }) = event else {
            return None;
        };
        let zones = self.fanout.live.zones();
        match zones.iter().find(|z| &z.id == zone)?.kind {
            ZoneKind::Hazard => Some("hazard"),
            ZoneKind::Restricted => Some("restricted"),
            ZoneKind::AreaOfInterest => None,
        }
    }

    /// Remembers an entry's time; returns the matching entry's time for an exit.
    fn track_zone_entry(&mut self, event: &ZoneEvent) -> Option<f64> {
        match event {
            ZoneEvent::Enter { tag, zone, time_s } => {
                self.zone_entries.insert((tag.clone(), zone.clone()), *time_s);
                None
            }
            ZoneEvent::Exit { tag, zone, .. } => self.zone_entries.remove(&(tag.clone(), zone.clone())),
            ZoneEvent::Dwell { .. } => None,
        }
    }
}

/// A tag as one MQTT topic level: `/`, `+` and `#` would change the topic's structure.
fn mqtt_level(tag: &str) -> String {
    tag.replace(['/', '+', '#'], "_")
}

/// Why a record was not used, for the log: a rejection's reason, or how late a late record
/// was.
fn unused_reason(event: &Value) -> String {
    match (event["reason"].as_str(), event["lateness_s"].as_f64()) {
        (Some(reason), _) => reason.to_string(),
        (None, Some(lateness_s)) => format!("{lateness_s:.3} s behind its track (beyond the rewind horizon)"),
        (None, None) => String::new(),
    }
}
