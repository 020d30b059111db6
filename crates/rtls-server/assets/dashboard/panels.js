// The side panels: alarm console, zones (head counts, who is inside), reader health, replay.
"use strict";

const SEVERITY = {
  "hazard-predicted": (a) => (a.time_to_entry_s !== undefined && a.time_to_entry_s <= 3 ? "critical" : "warning"),
  "no-coverage": () => "warning",
  lifecycle: (a) => (a.event === "lost" ? "critical" : "info"),
  "zone-enter": (a) => (a.zone_kind === "hazard" ? "critical" : "warning"),
};

function alarmText(a) {
  switch (a.type) {
    case "hazard-predicted":
      return `hazard predicted in ${Number(a.time_to_entry_s).toFixed(1)} s (p ${Number(a.probability).toFixed(2)})`;
    case "hazard-cleared": return "hazard cleared";
    case "zone-enter": return `entered ${a.zone_kind || ""} zone`;
    case "no-coverage": return "no coverage";
    case "model-switch": return `model switch → ${a.to || a.mode || ""}`;
    case "lifecycle": return a.event === "lost" ? "lost (last known position shown)" : a.event;
    default: return a.type;
  }
}

function formatTime(t) {
  if (t === undefined || t === null) return "";
  return new Date(t * 1000).toLocaleTimeString([], { hour12: false });
}

function cell(row, content) {
  const td = document.createElement("td");
  if (content instanceof Node) td.appendChild(content); else td.textContent = content ?? "";
  row.appendChild(td);
  return td;
}

function tagButton(tag, label, onTag) {
  const b = document.createElement("button");
  b.type = "button";
  b.className = "tag-link";
  b.textContent = label;
  b.addEventListener("click", () => onTag(tag));
  return b;
}

// The alarm console: alarms with an id can be acknowledged; the others (cleared, recovered,
// model switch) are shown for context. Newest first, at most `limit` rows.
class AlarmConsole {
  constructor(table, { onAcknowledge, onTag, nameOf, limit = 500, readOnly = false }) {
    this.readOnly = readOnly;
    this.body = table.tBodies[0];
    this.onAcknowledge = onAcknowledge;
    this.onTag = onTag;
    this.nameOf = nameOf;
    this.limit = limit;
    this.entries = []; // newest first
    this.byId = new Map();
    this.onChange = () => {};
  }

  unacknowledged() {
    let n = 0;
    for (const a of this.byId.values()) if (!a.acknowledged) n += 1;
    return n;
  }

  load(alarms) {
    // the API answers newest first
    for (const a of alarms.slice().reverse()) this.add(a, false);
    this.render();
  }

  add(alarm, render = true) {
    if (alarm.type === "alarm-acknowledged") {
      const a = this.byId.get(alarm.alarm_id);
      if (a) a.acknowledged = { by: alarm.by, at: alarm.timestamp };
    } else {
      if (alarm.alarm_id && this.byId.has(alarm.alarm_id)) return;
      this.entries.unshift(alarm);
      if (alarm.alarm_id) this.byId.set(alarm.alarm_id, alarm);
      while (this.entries.length > this.limit) {
        const old = this.entries.pop();
        if (old.alarm_id) this.byId.delete(old.alarm_id);
      }
      if (render && alarm.alarm_id && this.beep) this.beep(alarm);
    }
    if (render) this.render();
  }

  render() {
    const rows = this.entries.map((a) => {
      const tr = document.createElement("tr");
      const severity = (SEVERITY[a.type] || (() => "info"))(a);
      tr.className = `severity-${severity}${a.acknowledged ? " acknowledged" : ""}`;
      if (a.alarm_id) tr.dataset.alarmId = a.alarm_id;
      cell(tr, formatTime(a.t));
      cell(tr, a.tag ? tagButton(a.tag, this.nameOf(a.tag), this.onTag) : "");
      cell(tr, alarmText(a)).title = severity;
      cell(tr, a.zone || "");
      if (a.alarm_id && !a.acknowledged && !this.readOnly) {
        const b = document.createElement("button");
        b.type = "button";
        b.textContent = "Acknowledge";
        b.className = "acknowledge";
        b.addEventListener("click", () => this.onAcknowledge(a.alarm_id));
        cell(tr, b);
      } else {
        cell(tr, a.acknowledged ? `ack ${a.acknowledged.by}` : "");
      }
      return tr;
    });
    this.body.replaceChildren(...rows);
    this.onChange();
  }
}

// Zones: kind, head count and who is inside (muster board).
function renderZones(table, zones, occupants, { onTag, nameOf, onDelete, onEdit }) {
  const rows = (zones.features || []).map((f) => {
    const id = f.properties.id;
    const inside = occupants[id] || [];
    const tr = document.createElement("tr");
    tr.dataset.zoneId = id;
    cell(tr, f.properties.name || id);
    cell(tr, f.properties["rtls:kind"] || "");
    cell(tr, String(inside.length)).className = "head-count";
    const names = document.createElement("span");
    inside.forEach((tag, i) => {
      if (i) names.appendChild(document.createTextNode(", "));
      names.appendChild(tagButton(tag, nameOf(tag), onTag));
    });
    cell(tr, names);
    const remove = document.createElement("button");
    remove.type = "button";
    remove.className = "zone-delete";
    remove.textContent = "Delete";
    remove.addEventListener("click", () => onDelete(f.properties.id, f.properties.name || id));
    const edit = document.createElement("button");
    edit.type = "button";
    edit.className = "zone-edit";
    edit.textContent = "Edit";
    edit.addEventListener("click", () => onEdit(f));
    const actions = document.createElement("span");
    actions.append(edit, remove);
    cell(tr, actions);
    return tr;
  });
  table.tBodies[0].replaceChildren(...rows);
}

// Reader health: silent or never-heard readers first.
function renderReaders(table, summary, readers) {
  const order = { silent: 0, "never-heard": 1, "not-in-site": 2, ok: 3 };
  const sorted = readers.slice().sort((a, b) => (order[a.status] - order[b.status]) || a.id.localeCompare(b.id));
  const now = Date.now();
  const rows = sorted.map((r) => {
    const tr = document.createElement("tr");
    tr.className = r.status;
    tr.dataset.readerId = r.id;
    cell(tr, r.id);
    cell(tr, r.working_in_site ? r.status : `${r.status} (marked broken in the site)`);
    cell(tr, r.last_heard_ms ? `${((now - r.last_heard_ms) / 1000).toFixed(0)} s ago` : "never");
    cell(tr, `${r.rate_hz.toFixed(1)} /s`);
    // the range offset the tracks learnt (mean over tags, and their spread), m
    const o = r.range_offset;
    cell(tr, o ? `${o.mean_m >= 0 ? "+" : ""}${o.mean_m.toFixed(2)} m (${o.tags} tag${o.tags === 1 ? "" : "s"}, ${o.min_m.toFixed(2)}…${o.max_m.toFixed(2)})` : "–");
    return tr;
  });
  table.tBodies[0].replaceChildren(...rows);
  const silent = readers.filter((r) => r.status === "silent").length;
  const never = readers.filter((r) => r.status === "never-heard").length;
  summary.textContent = `${readers.length} readers, ${silent} silent, ${never} never heard`;
  summary.dataset.silent = String(silent);
}

// History replay: every tag's stored states in a range, played at 1–60× on the map with
// trails, and the alarms of that time in the console's place.
class Replay {
  constructor(map, { api, onStatus, onFrame }) {
    this.map = map;
    this.api = api;
    this.onStatus = onStatus;
    this.onFrame = onFrame;
    this.states = []; // [t, tag, state], by time
    this.index = 0;
    this.clock = 0;
    this.playing = false;
    this.speed = 10;
    this.active = false;
  }

  async load(fromS, toS) {
    const rows = await this.api(`/api/v1/history?from=${fromS}&to=${toS}&limit=100000`);
    this.states = rows.map((line) => [line.t, line.tag, stateFromTrackLine(line)]);
    this.fromS = fromS;
    this.toS = toS;
    this.active = true;
    this.seek(fromS);
    this.onStatus(`Replay: ${this.states.length} states of ${new Set(rows.map((r) => r.tag)).size} tags`);
    return this.states.length;
  }

  // Shows the state of every tag at `t` (the latest state at or before it), trails from the start.
  seek(t) {
    this.map.clearTags();
    this.clock = t;
    this.index = 0;
    for (const tag of new Set(this.states.map((s) => s[1]))) this.map.trails.set(tag, []);
    this.advanceTo(t);
  }

  advanceTo(t) {
    while (this.index < this.states.length && this.states[this.index][0] <= t) {
      const [, tag, state] = this.states[this.index];
      this.map.update(tag, state);
      this.index += 1;
    }
    this.clock = t;
    this.onFrame(t);
  }

  play() {
    if (this.playing) return;
    this.playing = true;
    let last = performance.now();
    const tick = (now) => {
      if (!this.playing) return;
      const dt = (now - last) / 1000;
      last = now;
      const next = Math.min(this.clock + dt * this.speed, this.toS);
      this.advanceTo(next);
      if (next >= this.toS) { this.playing = false; this.onFrame(next); return; }
      requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
  }

  pause() { this.playing = false; }

  step(seconds) { this.pause(); this.advanceTo(Math.min(this.clock + seconds, this.toS)); }

  stop() { this.pause(); this.active = false; this.states = []; this.map.clearTags(); }
}

// Muster board (GET /api/v1/muster): who is on site by the entry zone's check-in/check-out
// rule — missing people (on site, no longer heard) first.
const MUSTER_LABEL = { missing: "MISSING", "at-entry": "at entry", "on-site": "on site" };
function renderMuster(table, summary, board, { onTag, nameOf }) {
  if (!board.configured) {
    summary.textContent = "No muster rule: the site file has no [muster] entry_zone.";
    summary.dataset.onSite = "";
    table.tBodies[0].replaceChildren();
    return;
  }
  const c = board.counts;
  summary.dataset.onSite = String(board.on_site_total);
  summary.dataset.missing = String(c.missing);
  let text = `${board.on_site_total} on site (${c.missing} missing, ${c["at-entry"]} at the entry ${board.entry_zone}) · ${c["off-site"]} checked out`;
  if (board.missing_zones.length) text += ` · zones of the rule deleted: ${board.missing_zones.join(", ")}`;
  summary.textContent = text;
  const now = Date.now() / 1000;
  const rows = board.tags.map((t) => {
    const tr = document.createElement("tr");
    tr.className = `muster-${t.status}`;
    cell(tr, tagButton(t.tag, nameOf(t.tag), onTag));
    cell(tr, MUSTER_LABEL[t.status] || t.status);
    cell(tr, formatTime(t.time_s));
    cell(tr, t.status === "missing" ? `${Math.round(now - t.time_s)} s ago at ${t.position_m[0].toFixed(0)}, ${t.position_m[1].toFixed(0)} m` : "");
    return tr;
  });
  table.tBodies[0].replaceChildren(...rows);
}
