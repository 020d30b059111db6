// The control room: wires the map and panels to the server's API and WebSocket.
// Tokens: kept in localStorage; a `?token=` in the page's address is taken as the read token.
"use strict";

const $ = (id) => document.getElementById(id);
const store = window.localStorage;
const params = new URLSearchParams(location.search);
if (params.get("token")) store.setItem("rtls.readToken", params.get("token"));
if (params.get("write_token")) store.setItem("rtls.writeToken", params.get("write_token"));

async function api(path, { method = "GET", body, write = false } = {}) {
  const token = store.getItem(write ? "rtls.writeToken" : "rtls.readToken");
  const headers = {};
  if (token) headers.Authorization = `Bearer ${token}`;
  if (body !== undefined) headers["Content-Type"] = "application/json";
  const response = await fetch(path, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
  if (response.status === 401 || response.status === 403) {
    setConnection("unauthorised");
    if (!$("token-dialog").open) $("token-dialog").showModal();
    throw new Error(`${path}: ${response.status}`);
  }
  if (!response.ok) {
    const error = await response.json().catch(() => ({}));
    throw new Error(`${path}: ${response.status} ${error.message || ""}`);
  }
  return response.status === 204 ? null : response.json();
}

async function apiBlob(path) {
  const token = store.getItem("rtls.readToken");
  const response = await fetch(path, { headers: token ? { Authorization: `Bearer ${token}` } : {} });
  if (!response.ok) throw new Error(`${path}: ${response.status}`);
  return response.blob();
}

function setConnection(state) {
  const el = $("connection");
  el.dataset.state = state;
  el.textContent = { open: "live", connecting: "connecting", closed: "disconnected — retrying", unauthorised: "token needed" }[state] || state;
}

const map = new SiteMap($("map"));
// every tag's latest live state (the map shows these, or a replay's)
const liveTags = new Map();
function setLive(tag, state) {
  const added = !liveTags.has(tag);
  liveTags.set(tag, state);
  // the text count follows a new tag at once, not at the next reconciliation
  if (added) updateSummary();
  if (!replay.active) map.update(tag, state);
}
// the state of entry i of an rtls:positions column set (the topic's messages and the
// /api/v1/positions snapshot have the same shape)
function stateFromColumns(c, i) {
  const cov = c.cxx[i] === null ? null : [c.cxx[i], c.cxy[i], c.cxy[i], c.cyy[i]];
  return { x: c.x[i], y: c.y[i], z: c.z[i], cov, status: c.status[i] || "confirmed", predicted: c.predicted[i] === 1, t: c.t[i] };
}
// the server's tag list is the truth: tags it deleted leave, missed updates are caught up
// (its columnar snapshot: a fraction of the bytes and parse time of /api/v1/tags)
async function reconcileTags() {
  const columns = await api("/api/v1/positions");
  const present = new Set(columns.tag);
  columns.tag.forEach((tag, i) => {
    const known = liveTags.get(tag);
    const knownS = known && (known.t ?? Date.parse(known.timestamp) / 1000);
    if (!known || !(knownS >= columns.t[i])) setLive(tag, stateFromColumns(columns, i));
  });
  for (const tag of [...liveTags.keys()]) {
    if (!present.has(tag)) {
      liveTags.delete(tag);
      if (!replay.active) map.remove(tag);
    }
  }
  updateSummary();
}

const nameOf = (tag) => map.names.get(tag) || tag;
const focusTag = (tag) => {
  map.follow(tag);
  $("unfollow").hidden = false;
  $("tag-search").value = nameOf(tag);
};
map.onSelect = focusTag;

const alarms = new AlarmConsole($("alarm-table"), {
  onAcknowledge: async (id) => {
    try {
      await api(`/api/v1/alarms/${id}/acknowledge`, { method: "POST", write: true, body: { by: store.getItem("rtls.operator") || "operator" } });
    } catch (e) {
      console.warn(e);
    }
  },
  onTag: focusTag,
  nameOf,
});
let audio = null;
alarms.beep = () => {
  if (!$("sound").checked) return;
  audio = audio || new AudioContext();
  const osc = audio.createOscillator();
  osc.frequency.value = 880;
  osc.connect(audio.destination);
  osc.start();
  osc.stop(audio.currentTime + 0.2);
};

// The page's text summary: live tags (not replayed ones) and unacknowledged alarms.
function updateSummary() {
  const live = liveTags.size;
  $("live-count").dataset.count = String(live);
  $("live-count").textContent = `${live} live tag${live === 1 ? "" : "s"}`;
  const open = alarms.unacknowledged();
  $("alarm-count").dataset.count = String(open);
  $("alarm-count").textContent = `${open} unacknowledged alarm${open === 1 ? "" : "s"}`;
}
alarms.onChange = updateSummary;

const replay = new Replay(map, {
  api,
  onStatus: (text) => { $("replay-status").textContent = text; },
  onFrame: (t) => {
    $("replay-clock").textContent = `${new Date(t * 1000).toLocaleString()} (${replay.speed}×${replay.playing ? ", playing" : ""})`;
    $("replay-clock").dataset.t = String(t);
    const span = replay.toS - replay.fromS;
    if (span > 0) $("replay-position").value = String(Math.round((1000 * (t - replay.fromS)) / span));
    showReplayAlarms(t);
  },
});

// ── WebSocket: locations and alarms ──────────────────────────────────────────────────────────
let socket = null;
// one WebSocket message (the server batches: a payload holds every update of an output tick)
function handleMessage(topic, message) {
  for (const payload of message.payload || []) {
    if (topic === "rtls:positions") {
      // columns: one array per field, one entry per update
      for (let i = 0; i < payload.tag.length; i += 1) setLive(payload.tag[i], stateFromColumns(payload, i));
    } else if (topic === "location_updates") {
      setLive(payload.provider_id, stateFromLocation(payload));
    } else if (topic === "rtls:alarms") {
      alarms.add(payload);
    }
  }
}
function connect() {
  setConnection("connecting");
  const token = store.getItem("rtls.readToken");
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  socket = new WebSocket(`${scheme}://${location.host}/v2/ws/socket${token ? `?token=${encodeURIComponent(token)}` : ""}`);
  const topics = new Map();
  socket.onopen = () => {
    setConnection("open");
    // rtls:positions: the location updates in columns, parsed several times faster than
    // omlox Location objects (the map's budget at ten thousand tags)
    for (const topic of ["rtls:positions", "rtls:alarms"]) socket.send(JSON.stringify({ event: "subscribe", topic }));
  };
  socket.onmessage = (event) => {
    const message = JSON.parse(event.data);
    if (message.event === "subscribed") { topics.set(message.subscription_id, message.topic); return; }
    if (message.event !== "message") return;
    handleMessage(message.topic || topics.get(message.subscription_id), message);
  };
  socket.onclose = () => {
    setConnection("closed");
    setTimeout(connect, 2000);
  };
}

// ── Periodic panels ──────────────────────────────────────────────────────────────────────────
let zones = { features: [] };

// ── Zone editor: draw on the map, stored through omlox fences ────────────────────────────────
map.onDrawn = (n) => {
  $("zone-hint").textContent = n < 3 ? `${n} point${n === 1 ? "" : "s"}: click at least 3` : `${n} points: Save or add more`;
  $("zone-save").disabled = n < 3;
};
$("zone-draw").addEventListener("click", () => {
  map.startDrawing();
  $("zone-cancel").disabled = false;
  $("zone-hint").textContent = "click the map to place the corners";
});
$("zone-cancel").addEventListener("click", () => {
  map.cancelDrawing();
  endEditing();
  $("zone-save").disabled = true;
  $("zone-cancel").disabled = true;
  $("zone-hint").textContent = "";
});
// Editing an existing zone: its feature while its corners are being moved, else null.
let editingZone = null;
function endEditing() {
  map.stopEditing();
  editingZone = null;
  $("zone-editing").hidden = true;
  $("zone-draw").disabled = false;
}
function editZone(feature) {
  map.cancelDrawing();
  editingZone = feature;
  const p = feature.properties;
  $("zone-name").value = p.name || p.id;
  $("zone-kind").value = p["rtls:kind"] || "area-of-interest";
  $("zone-editing-name").textContent = p.name || p.id;
  $("zone-editing").hidden = false;
  $("zone-draw").disabled = true;
  $("zone-save").disabled = false;
  $("zone-cancel").disabled = false;
  $("zone-hint").textContent = "drag the corners, then Save";
  map.startEditing(p.id, (vertices) => { $("zone-hint").textContent = `${vertices.length} corners moved: Save or Cancel`; });
}
$("zone-editor").addEventListener("submit", async (e) => {
  e.preventDefault();
  const editing = editingZone;
  const vertices = editing ? map.stopEditing() : map.finishDrawing();
  if (editing) endEditing();
  $("zone-save").disabled = true;
  $("zone-cancel").disabled = true;
  const ring = [...vertices, vertices[0]];
  const properties = { "rtls:kind": $("zone-kind").value };
  const name = $("zone-name").value.trim() || "New zone";
  const region = { type: "Polygon", coordinates: [ring] };
  // the map draws in site metres; a fence without crs would be EPSG:4326 (omlox's default)
  const crs = "local";
  try {
    if (editing) {
      // the zone keeps its id and height: its floor or its height range
      const old = editing.properties;
      if (old["rtls:floor"]) properties["rtls:floor"] = old["rtls:floor"];
      else if (old["rtls:z_range_m"]) properties["rtls:z_range_m"] = old["rtls:z_range_m"];
      // 204: omlox answers a replaced fence with no body
      await api(`/v2/fences/${encodeURIComponent(old.id)}`, { method: "PUT", write: true, body: { name, crs, region, properties } });
      $("zone-hint").textContent = `saved: ${name}`;
    } else {
      if (map.floor) properties["rtls:floor"] = map.floor.id;
      const fence = await api("/v2/fences", { method: "POST", write: true, body: { name, crs, region, properties } });
      $("zone-hint").textContent = `saved: ${fence.name}`;
    }
  } catch (error) {
    $("zone-hint").textContent = `not saved: ${error.message}`;
  }
  await refreshZones();
});
async function deleteZone(id, name) {
  if (!window.confirm(`Delete zone ${name}?`)) return;
  try {
    await api(`/v2/fences/${encodeURIComponent(id)}`, { method: "DELETE", write: true });
  } catch (error) {
    $("zone-hint").textContent = `not deleted: ${error.message}`;
  }
  await refreshZones();
}
async function refreshZones() {
  const [collection, occupants] = await Promise.all([api("/api/v1/zones.geojson?crs=local"), api("/api/v1/zones/occupants")]);
  zones = collection;
  renderZones($("zone-table"), zones, occupants, { onTag: focusTag, nameOf, onDelete: deleteZone, onEdit: editZone });
  map.setZones(zones);
  let live = 0;
  for (const s of liveTags.values()) if (s.status !== "lost") live += 1;
  $("on-site").textContent = `${live} tags tracked now (not lost)`;
}

async function refreshMuster() {
  const board = await api("/api/v1/muster");
  renderMuster($("muster-table"), $("muster-summary"), board, { onTag: focusTag, nameOf });
}

// Floor-plan images are fetched with the read token (an <img> cannot send it) and shown from
// object URLs.
async function loadPlans(site) {
  const images = new Map();
  for (const floor of site.floors) {
    if (!floor.plan) continue;
    try {
      images.set(floor.id, URL.createObjectURL(await apiBlob(floor.plan.url)));
    } catch (error) {
      console.warn(`floor ${floor.id}: plan image not loaded: ${error.message}`);
    }
  }
  map.setPlans(images);
}

async function refreshReaders() {
  const readers = await api("/api/v1/readers");
  renderReaders($("reader-table"), $("reader-summary"), readers);
  map.setReaderHealth(readers);
}

async function refreshNames() {
  // omlox trackables name their location providers (our tags)
  const trackables = await api("/v2/trackables/summary").catch(() => []);
  const known = map.names.size;
  for (const t of trackables) for (const provider of t.location_providers || []) map.names.set(provider, t.name || provider);
  // rows drawn before a name was known show it now
  if (map.names.size !== known) {
    alarms.render();
    map.invalidate();
  }
  const list = $("tag-list");
  list.replaceChildren(...[...liveTags.keys()].sort().map((tag) => {
    const option = document.createElement("option");
    option.value = nameOf(tag);
    option.dataset.tag = tag;
    return option;
  }));
}

function every(ms, task) {
  const run = () => task().catch((e) => console.warn(e)).finally(() => setTimeout(run, ms));
  run();
}

// ── Controls ─────────────────────────────────────────────────────────────────────────────────
for (const tab of document.querySelectorAll("nav button")) {
  tab.addEventListener("click", () => {
    for (const other of document.querySelectorAll("nav button")) {
      other.setAttribute("aria-selected", String(other === tab));
      $(`panel-${other.dataset.panel}`).hidden = other !== tab;
    }
  });
}
$("floor-select").addEventListener("change", (e) => map.setFloor(e.target.value || null));
$("tag-search").addEventListener("change", (e) => {
  const wanted = e.target.value.trim();
  for (const tag of liveTags.keys()) {
    if (tag === wanted || nameOf(tag) === wanted) { focusTag(tag); return; }
  }
});
$("unfollow").addEventListener("click", () => { map.follow(null); $("unfollow").hidden = true; });
$("token-button").addEventListener("click", () => {
  $("read-token").value = store.getItem("rtls.readToken") || "";
  $("write-token").value = store.getItem("rtls.writeToken") || "";
  $("operator-name").value = store.getItem("rtls.operator") || "";
  $("token-dialog").showModal();
});
$("token-dialog").addEventListener("close", () => {
  store.setItem("rtls.readToken", $("read-token").value.trim());
  store.setItem("rtls.writeToken", $("write-token").value.trim());
  store.setItem("rtls.operator", $("operator-name").value.trim());
  location.reload();
});

const toLocalInput = (unixS) => {
  const d = new Date(unixS * 1000);
  return new Date(d.getTime() - d.getTimezoneOffset() * 60000).toISOString().slice(0, 19);
};
const fromLocalInput = (value) => new Date(value).getTime() / 1000;
$("replay-from").value = toLocalInput(Date.now() / 1000 - 120);
$("replay-to").value = toLocalInput(Date.now() / 1000 - 60);
$("replay-form").addEventListener("submit", async (e) => {
  e.preventDefault();
  const fromS = fromLocalInput($("replay-from").value);
  const toS = fromLocalInput($("replay-to").value);
  await replay.load(fromS, toS);
  $("replay-controls").hidden = false;
  const q = `from=${fromS}&to=${toS}`;
  $("replay-export").innerHTML = `Export: <a href="/api/v1/history?${q}&format=csv">CSV</a> · <a href="/api/v1/history?${q}&format=geojson">GeoJSON</a> · <a href="/api/v1/alarms?${q}">alarms</a>`;
  const past = await api(`/api/v1/alarms?${q}`);
  replayAlarms = past;
  replayAlarmsShown = -1;
  showReplayAlarms(replay.clock);
  updateSummary();
});
let replayAlarms = [];
let replayAlarmsShown = -1;
const replayConsole = new AlarmConsole($("replay-alarm-table"), { onAcknowledge: () => {}, onTag: focusTag, nameOf, limit: 100, readOnly: true });
// the alarms raised up to replay time t (the API answers newest first)
function showReplayAlarms(t) {
  const upTo = replayAlarms.filter((a) => a.t <= t);
  if (upTo.length === replayAlarmsShown) return;
  replayAlarmsShown = upTo.length;
  replayConsole.entries = upTo.slice(0, 100);
  replayConsole.byId = new Map();
  replayConsole.render();
}
$("replay-play").addEventListener("click", () => { if (replay.playing) replay.pause(); else replay.play(); });
$("replay-step").addEventListener("click", () => replay.step(1));
$("replay-speed").addEventListener("change", (e) => { replay.speed = Number(e.target.value); });
$("replay-position").addEventListener("input", (e) => {
  replay.pause();
  replay.seek(replay.fromS + (Number(e.target.value) / 1000) * (replay.toS - replay.fromS));
});
$("replay-live").addEventListener("click", async () => {
  replay.stop();
  $("replay-controls").hidden = true;
  $("replay-status").textContent = "Live";
  for (const [tag, state] of liveTags) map.update(tag, state);
  updateSummary();
});

// ── Start ────────────────────────────────────────────────────────────────────────────────────
async function start() {
  const site = await api("/api/v1/site");
  $("site-name").textContent = site.name ? `rtls — ${site.name}` : "rtls";
  document.title = $("site-name").textContent;
  map.setSite(site);
  const select = $("floor-select");
  select.replaceChildren(new Option("all floors", ""), ...site.floors.map((f) => new Option(f.id, f.id)));
  select.disabled = site.floors.length === 0;
  map.setZones(await api("/api/v1/zones.geojson?crs=local"));
  loadPlans(site);
  // the tags' latest states first, so the map is full before the first WebSocket update
  await reconcileTags();
  await refreshNames();
  alarms.load(await api("/api/v1/alarms?limit=200"));
  connect();
  every(5000, reconcileTags);
  every(2000, refreshZones);
  every(5000, refreshReaders);
  every(2000, refreshMuster);
  setTimeout(() => every(10000, refreshNames), 10000);
}
start().catch((e) => { console.error(e); setConnection("closed"); });
window.rtls = { map, alarms, replay, api, liveTags, handleMessage };
