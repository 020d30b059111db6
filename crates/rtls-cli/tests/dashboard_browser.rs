//! The control-room dashboard in a real browser: Debian's `chromium`, headless, driven over the
//! DevTools protocol (`headless_chrome`). `.ci/run` installs chromium and sets `RTLS_CHROMIUM`;
//! elsewhere `/usr/bin/chromium` is used when installed, and without either the tests print a
//! notice and pass. With `RTLS_SCREENSHOTS=DIR` the tests also save
//! a screenshot of each view there (the docs' pictures).
//!
//! What a control room relies on is checked through the page, as an operator sees it: the
//! text count of live tags equals `/api/v1/tags`; an alarm acknowledged on one screen shows as
//! acknowledged on another and in the API, with who did it; a zone drawn and then reshaped by
//! dragging its corners counts the miners inside as the API does; the muster board's count
//! equals the API's; a minute of history replays; the floor switch shows one floor's tags,
//! zones and floor-plan image.

mod common;
mod devtools;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use headless_chrome::protocol::cdp::Page::CaptureScreenshotFormatOption;
use headless_chrome::{Browser, Tab};
use serde_json::Value;

const READ: &str = "dashboard-read-token";
const WRITE: &str = "dashboard-write-token";

/// `rtls serve` with `args`, on loopback ports of its own; killed when dropped.
struct Server {
    _child: common::KillOnDrop,
    http: String,
}

fn serve(name: &str, args: &[&str]) -> Server {
    let dir = common::temp_dir("dashboard", name);
    let served = common::serve(args, &dir.join("dashboard.db"), WRITE, READ);
    Server {
        http: served.http(),
        _child: served.child,
    }
}

/// Headless chromium: `RTLS_CHROMIUM` (which must exist: `.ci/run` sets it), else Debian's
/// `/usr/bin/chromium` when installed; `None` (the test prints a notice and passes, as the
/// mosquitto and PostgreSQL tests do without their services) when neither is there.
fn browser() -> Option<Browser> {
    let path = match std::env::var_os("RTLS_CHROMIUM") {
        Some(path) => {
            let path = PathBuf::from(path);
            assert!(path.exists(), "RTLS_CHROMIUM={} does not exist", path.display());
            path
        }
        None if std::path::Path::new("/usr/bin/chromium").exists() => PathBuf::from("/usr/bin/chromium"),
        None => {
            eprintln!(
                "notice: the dashboard's browser tests did not run: install chromium (`apt-get install chromium`, \
                 as .ci/run does) or set RTLS_CHROMIUM to a Chrome/Chromium binary"
            );
            return None;
        }
    };
    Some(devtools::launch(path).unwrap_or_else(|e| panic!("{e}")))
}

/// [`devtools::eval`]; an exception fails the test with its message.
fn eval(tab: &Tab, expression: &str) -> Value {
    devtools::eval(tab, expression).unwrap_or_else(|e| panic!("{e}"))
}

/// Polls `expression` until it is truthy (not false, null, 0 or ""); returns its value.
fn wait_for(tab: &Tab, expression: &str, timeout: Duration, what: &str) -> Value {
    wait_until(tab, expression, truthy, timeout, what)
}

fn truthy(value: &Value) -> bool {
    match value {
        Value::Null => false,
        Value::Bool(b) => *b,
        Value::Number(n) => n.as_f64() != Some(0.0),
        Value::String(s) => !s.is_empty(),
        _ => true,
    }
}

/// Polls `expression` until `done` holds for its value; returns the value.
fn wait_until(tab: &Tab, expression: &str, done: impl Fn(&Value) -> bool, timeout: Duration, what: &str) -> Value {
    let deadline = Instant::now() + timeout;
    loop {
        let value = eval(tab, expression);
        if done(&value) {
            return value;
        }
        assert!(
            Instant::now() < deadline,
            "{what}: not within {timeout:?} (last value {value})"
        );
        std::thread::sleep(Duration::from_millis(250));
    }
}

/// Drags with the left mouse button from `from` to `to` (page pixels) in ten moves, as a hand
/// does: Leaflet's marker dragging reads the moves between press and release.
fn drag(tab: &Tab, from: (f64, f64), to: (f64, f64)) {
    use headless_chrome::protocol::cdp::Input::{DispatchMouseEvent, DispatchMouseEventTypeOption, MouseButton};
    let event = |kind: DispatchMouseEventTypeOption, (x, y): (f64, f64)| DispatchMouseEvent {
        Type: kind,
        x,
        y,
        modifiers: None,
        timestamp: None,
        button: Some(MouseButton::Left),
        buttons: Some(1),
        click_count: Some(1),
        force: None,
        tangential_pressure: None,
        tilt_x: None,
        tilt_y: None,
        twist: None,
        delta_x: None,
        delta_y: None,
        pointer_Type: None,
    };
    tab.move_mouse_to_point(headless_chrome::browser::tab::point::Point { x: from.0, y: from.1 })
        .unwrap();
    tab.call_method(event(DispatchMouseEventTypeOption::MousePressed, from))
        .unwrap();
    for k in 1..=10 {
        let f = f64::from(k) / 10.0;
        let at = (from.0 + f * (to.0 - from.0), from.1 + f * (to.1 - from.1));
        tab.call_method(event(DispatchMouseEventTypeOption::MouseMoved, at))
            .unwrap();
    }
    tab.call_method(event(DispatchMouseEventTypeOption::MouseReleased, to))
        .unwrap();
}

/// Whether the page's counts agree: the API's tags, the text count, the tags drawn.
fn counts_agree(c: &Value) -> bool {
    c["api"].as_u64().is_some_and(|n| n >= 50) && c["api"] == c["screen"] && c["drawn"] == c["api"]
}

/// A `fetch` of the server's API from the page with `token`, as JSON.
fn api_js(path: &str, token: &str) -> String {
    format!("fetch('{path}', {{ headers: {{ Authorization: 'Bearer {token}' }} }}).then(r => r.json())")
}

fn screenshot(tab: &Tab, name: &str) {
    let Some(dir) = std::env::var_os("RTLS_SCREENSHOTS") else {
        return;
    };
    let png = tab
        .capture_screenshot(CaptureScreenshotFormatOption::Png, None, None, true)
        .unwrap();
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(PathBuf::from(dir).join(format!("{name}.png")), png).unwrap();
}

/// The dashboard in a new browser context of its own (its own storage: another operator's
/// screen), with the tokens in the address and `operator` as the name acknowledgements carry.
fn open_dashboard(browser: &Browser, server: &Server, operator: &str) -> std::sync::Arc<Tab> {
    let tab = browser.new_context().unwrap().new_tab().unwrap();
    tab.navigate_to(&format!("http://{}/?token={READ}&write_token={WRITE}", server.http))
        .unwrap()
        .wait_until_navigated()
        .unwrap();
    eval(
        &tab,
        &format!("localStorage.setItem('rtls.operator', '{operator}'); true"),
    );
    tab
}

#[test]
fn the_demo_on_screen_counts_its_tags_acknowledges_an_alarm_everywhere_and_replays_a_minute() {
    let Some(browser) = browser() else { return };
    let server = serve("demo", &["--demo", "--demo-miners", "60"]);
    let tab = open_dashboard(&browser, &server, "shift lead A");
    let second_screen = open_dashboard(&browser, &server, "shift lead B");

    // the page states the live tag count in text; it equals the API's once the miners are in
    let counts = format!(
        "Promise.all([{}, Promise.resolve(document.getElementById('live-count'))]).then(([tags, el]) => \
         ({{ api: tags.length, screen: Number(el.dataset.count), text: el.textContent, \
            drawn: window.rtls.map.visibleCount(), frames: window.rtls.map.frames }}))",
        api_js("/api/v1/tags", READ)
    );
    let settled = wait_until(
        &tab,
        &counts,
        counts_agree,
        Duration::from_secs(60),
        "the on-screen tag count equals /api/v1/tags",
    );
    assert_eq!(settled["text"], format!("{} live tags", settled["api"]));
    assert!(settled["frames"].as_u64().unwrap() > 0, "{settled}");
    // names, not tag ids: the demo registers its crew as omlox trackables
    wait_for(
        &tab,
        "window.rtls.map.names.size >= 50 && window.rtls.map.names.get('miner-000') !== 'miner-000'",
        Duration::from_secs(30),
        "trackable names reach the map",
    );
    screenshot(&tab, "dashboard-live-map");

    // draw a zone over the western half of the mine with real clicks on the map, save it, and
    // see its head count become the number of miners inside it
    eval(
        &tab,
        "document.querySelector(\"nav button[data-panel='zones']\").click(); true",
    );
    tab.find_element("#zone-draw").unwrap().click().unwrap();
    let corners = eval(
        &tab,
        &format!(
            "{}.then(site => {{ const b = site.bounds_m; const mid = (b.min[0] + b.max[0]) / 2; \
             const map = window.rtls.map.map; const box = map.getContainer().getBoundingClientRect(); \
             return [[b.min[0] - 1, b.min[1] - 1], [mid, b.min[1] - 1], [mid, b.max[1] + 1], [b.min[0] - 1, b.max[1] + 1]] \
               .map(([x, y]) => {{ const p = map.latLngToContainerPoint([y, x]); return [box.left + p.x, box.top + p.y]; }}); }})",
            api_js("/api/v1/site", READ)
        ),
    );
    for corner in corners.as_array().unwrap() {
        let (x, y) = (corner[0].as_f64().unwrap(), corner[1].as_f64().unwrap());
        tab.click_point(headless_chrome::browser::tab::point::Point { x, y })
            .unwrap();
    }
    assert_eq!(
        eval(
            &tab,
            "window.rtls.map.drawing && window.rtls.map.drawing.vertices.length"
        ),
        4,
        "four corners placed by clicking the map"
    );
    eval(&tab, "document.getElementById('zone-name').value = 'West half'; true");
    tab.find_element("#zone-save").unwrap().click().unwrap();
    let west = wait_until(
        &tab,
        &format!(
            "Promise.all([{}, {}]).then(([fences, occupants]) => {{ const f = fences.find(f => f.name === 'West half'); \
             if (!f) return null; const row = document.querySelector(`tr[data-zone-id='${{f.foreign_id}}'] .head-count`); \
             return {{ id: f.foreign_id, api: (occupants[f.foreign_id] || []).length, screen: row ? Number(row.textContent) : -1 }}; }})",
            api_js("/v2/fences/summary?crs=local", READ),
            api_js("/api/v1/zones/occupants", READ)
        ),
        |v| v["api"].as_u64().is_some_and(|n| n >= 5) && v["screen"] == v["api"],
        Duration::from_secs(30),
        "the drawn zone's head count on screen equals the API's, with miners inside",
    );
    screenshot(&tab, "dashboard-zones");
    let id = west["id"].as_str().unwrap().to_string();

    // edit it: drag its two eastern corners past the mine's east end with the mouse, save, and
    // the stored fence and its head count follow
    // the zone table is rebuilt whenever zones or head counts change, so the row found here
    // may be replaced before the mouse reaches it (the click then fails: the element is gone)
    // or the click may land on a row being replaced; either way it is repeated on the row now
    // there (editing starts synchronously, so a click that took is never repeated)
    if let Ok(edit) = tab.find_element(&format!("tr[data-zone-id='{id}'] .zone-edit")) {
        let _ = edit.click();
    }
    wait_for(
        &tab,
        &format!(
            "(() => {{ const editing = () => window.rtls.map.editing && window.rtls.map.editing.zoneId === '{id}'; \
             if (!editing()) {{ const b = document.querySelector(\"tr[data-zone-id='{id}'] .zone-edit\"); if (b) b.click(); }} \
             return editing(); }})()"
        ),
        Duration::from_secs(10),
        "the zone's corners are editable after its row's Edit button",
    );
    let handles = eval(
        &tab,
        &format!(
            "{}.then(site => {{ const map = window.rtls.map.map; const box = map.getContainer().getBoundingClientRect();              const east = site.bounds_m.max[0] + 1;              return window.rtls.map.editing.handles.slice(1, 3).map(h => {{ const ll = h.getLatLng();                const from = map.latLngToContainerPoint(ll), to = map.latLngToContainerPoint([ll.lat, east]);                return [box.left + from.x, box.top + from.y, box.left + to.x, box.top + to.y]; }}); }})",
            api_js("/api/v1/site", READ)
        ),
    );
    for handle in handles.as_array().unwrap() {
        let p: Vec<f64> = handle.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        drag(&tab, (p[0], p[1]), (p[2], p[3]));
    }
    tab.find_element("#zone-save").unwrap().click().unwrap();
    let whole = wait_until(
        &tab,
        &format!(
            "Promise.all([{}, {}, {}]).then(([fences, occupants, site]) => {{ const f = fences.find(f => f.foreign_id === '{id}');              const xs = f.region.coordinates[0].map(p => p[0]);              const row = document.querySelector(`tr[data-zone-id='{id}'] .head-count`);              return {{ east: Math.max(...xs), mine_east: site.bounds_m.max[0], api: (occupants['{id}'] || []).length,                        screen: row ? Number(row.textContent) : -1 }}; }})",
            api_js("/v2/fences/summary?crs=local", READ),
            api_js("/api/v1/zones/occupants", READ),
            api_js("/api/v1/site", READ)
        ),
        |v| {
            v["east"].as_f64().zip(v["mine_east"].as_f64()).is_some_and(|(e, m)| (e - (m + 1.0)).abs() < 1.0)
                && v["screen"] == v["api"]
                // nearly the whole crew is inside the mine-wide zone now (some may be lost)
                && v["api"].as_u64().is_some_and(|n| n >= 50)
        },
        Duration::from_secs(30),
        "the dragged corners stored and the head count on screen equal to the API's",
    );
    eprintln!("zone edited by dragging its corners: {west} → {whole}");

    // the muster board: its text count equals the API's, missing people first
    eval(
        &tab,
        "document.querySelector(\"nav button[data-panel='muster']\").click(); true",
    );
    let muster = wait_until(
        &tab,
        &format!(
            "{}.then(board => ({{ api: board.on_site_total, screen: Number(document.getElementById('muster-summary').dataset.onSite), \
             rows: document.querySelectorAll('#muster-table tbody tr').length }}))",
            api_js("/api/v1/muster", READ)
        ),
        |v| v["api"].as_u64().is_some_and(|n| n >= 50) && v["screen"] == v["api"] && v["rows"] == v["api"],
        Duration::from_secs(30),
        "the muster board's count on screen equals the API's",
    );
    eprintln!("muster board: {muster}");
    screenshot(&tab, "dashboard-muster");

    // and it is stored as an omlox fence the trackers watch: deleting it through the API
    // removes it from the screen
    let status = eval(
        &tab,
        &format!(
            "fetch('/v2/fences/{id}', {{ method: 'DELETE', headers: {{ Authorization: 'Bearer {WRITE}' }} }}).then(r => r.status)"
        ),
    );
    assert_eq!(status, 204);
    wait_for(
        &tab,
        &format!("!document.querySelector(\"tr[data-zone-id='{id}']\")"),
        Duration::from_secs(10),
        "the deleted zone leaves the screen",
    );

    // reader health: one row per reader of the site, as the API lists them
    eval(
        &tab,
        "document.querySelector(\"nav button[data-panel='readers']\").click(); true",
    );
    let readers = wait_until(
        &tab,
        &format!(
            "{}.then(readers => ({{ api: readers.length, screen: document.querySelectorAll('#reader-table tbody tr').length }}))",
            api_js("/api/v1/readers", READ)
        ),
        |v| v["api"].as_u64().is_some_and(|n| n >= 300) && v["screen"] == v["api"],
        Duration::from_secs(20),
        "a row per reader on screen",
    );
    eprintln!("reader health: {readers}");
    screenshot(&tab, "dashboard-readers");
    eval(
        &tab,
        "document.querySelector(\"nav button[data-panel='alarms']\").click(); true",
    );

    // an alarm: the demo sends miners towards the roof fall, so hazard predictions come;
    // acknowledge the first one on screen A with a real click
    let alarm_id = wait_for(
        &tab,
        "(() => { const b = document.querySelector('button.acknowledge'); return b && b.closest('tr').dataset.alarmId; })()",
        Duration::from_secs(240),
        "an alarm to acknowledge on screen",
    );
    let alarm_id = alarm_id.as_str().unwrap().to_string();
    let unacknowledged_before = eval(&tab, "Number(document.getElementById('alarm-count').dataset.count)");
    assert!(unacknowledged_before.as_u64().unwrap() >= 1);
    screenshot(&tab, "dashboard-alarms");
    // clicked in the page: the console re-renders its rows as alarms arrive, so a node found
    // over DevTools may be replaced before a synthesised mouse click reaches it
    eval(
        &tab,
        &format!("document.querySelector(\"tr[data-alarm-id='{alarm_id}'] button.acknowledge\").click(); true"),
    );
    // the API has it, with who and when
    let acknowledged = wait_for(
        &tab,
        &format!(
            "{}.then(list => {{ const a = list.find(a => a.alarm_id === '{alarm_id}'); return a && a.acknowledged; }})",
            api_js("/api/v1/alarms", READ)
        ),
        Duration::from_secs(10),
        "the acknowledgement in /api/v1/alarms",
    );
    assert_eq!(acknowledged["by"], "shift lead A", "{acknowledged}");
    assert!(
        acknowledged["at"].as_str().is_some_and(|at| at.ends_with('Z')),
        "{acknowledged}"
    );
    // every open screen shows it (the WebSocket broadcast), and the history has the event
    for screen in [&tab, &second_screen] {
        wait_for(
            screen,
            &format!("document.querySelector(\"tr[data-alarm-id='{alarm_id}']\")?.classList.contains('acknowledged')"),
            Duration::from_secs(10),
            "the alarm shown acknowledged on both screens",
        );
    }
    let history = eval(
        &tab,
        &format!(
            "{}.then(events => events.filter(e => e.alarm_id === '{alarm_id}').length)",
            api_js("/api/v1/events?type=alarm-acknowledged", READ)
        ),
    );
    assert_eq!(history, 1);
    // a second acknowledgement keeps the first one's author
    let again = eval(
        &tab,
        &format!(
            "fetch('/api/v1/alarms/{alarm_id}/acknowledge', {{ method: 'POST', headers: {{ Authorization: 'Bearer {WRITE}' }}, \
             body: JSON.stringify({{ by: 'someone else' }}) }}).then(r => r.json())"
        ),
    );
    assert_eq!(again["by"], "shift lead A");

    // replay the last minute: load it, step, and the map shows replayed tags with trails
    eval(
        &tab,
        "(() => { document.querySelector(\"nav button[data-panel='replay']\").click(); \
          const local = (s) => { const d = new Date(s * 1000); \
            return new Date(d.getTime() - d.getTimezoneOffset() * 60000).toISOString().slice(0, 19); }; \
          const now = Date.now() / 1000; \
          document.getElementById('replay-from').value = local(now - 70); \
          document.getElementById('replay-to').value = local(now - 10); return true; })()",
    );
    tab.find_element("#replay-form button[type=submit]")
        .unwrap()
        .click()
        .unwrap();
    let status = wait_for(
        &tab,
        "(() => { const t = document.getElementById('replay-status').textContent; return t.startsWith('Replay:') && t; })()",
        Duration::from_secs(20),
        "the replay loaded",
    );
    let states: u64 = status
        .as_str()
        .unwrap()
        .split_whitespace()
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    assert!(states >= 60, "a minute of 60 miners has more states: {status}");
    let clock_before = eval(&tab, "Number(document.getElementById('replay-clock').dataset.t)");
    tab.find_element("#replay-step").unwrap().click().unwrap();
    let clock_after = eval(&tab, "Number(document.getElementById('replay-clock').dataset.t)");
    assert!(
        (clock_after.as_f64().unwrap() - clock_before.as_f64().unwrap() - 1.0).abs() < 1e-6,
        "{clock_before} → {clock_after}"
    );
    eval(&tab, "document.getElementById('replay-speed').value = '60'; document.getElementById('replay-speed').dispatchEvent(new Event('change')); true");
    tab.find_element("#replay-play").unwrap().click().unwrap();
    wait_for(
        &tab,
        "window.rtls.replay.clock >= window.rtls.replay.toS && window.rtls.map.tags.size >= 50 && \
         [...window.rtls.map.trails.values()].some(t => t.length > 5)",
        Duration::from_secs(20),
        "the replay played to its end at 60× with trails",
    );
    screenshot(&tab, "dashboard-replay");
    // back to live: the live count still equals the API's
    tab.find_element("#replay-live").unwrap().click().unwrap();
    wait_until(
        &tab,
        &counts,
        counts_agree,
        Duration::from_secs(20),
        "live again after the replay",
    );
}

#[test]
fn the_floor_switch_shows_one_floors_tags_and_zones() {
    let dir = common::temp_dir("dashboard", "floors-site");
    let site = dir.join("site.toml");
    std::fs::write(
        &site,
        r#"
name = "two floors"
[[readers]]
id = "A1"
position_m = [0.0, 0.0, 2.5]
technology = "uwb"
[[readers]]
id = "A2"
position_m = [20.0, 10.0, 2.5]
technology = "uwb"
[[floors]]
id = "ground"
z_range_m = [0.0, 3.5]
plan = { image = "ground.svg", bounds_m = [[-2.0, -2.0], [22.0, 12.0]] }
[[floors]]
id = "mezzanine"
z_range_m = [3.5, 7.0]
[[zones]]
id = "dock"
name = "Dock"
kind = "area-of-interest"
shape = { type = "polygon", vertices_m = [[0.0, 0.0], [8.0, 0.0], [8.0, 8.0], [0.0, 8.0]], floor = "ground" }
[[zones]]
id = "gallery"
name = "Gallery"
kind = "restricted"
shape = { type = "polygon", vertices_m = [[10.0, 0.0], [18.0, 0.0], [18.0, 8.0], [10.0, 8.0]], floor = "mezzanine" }
[tracker]
pipeline = "fix-then-filter"
dimensions = 3
"#,
    )
    .unwrap();
    std::fs::write(
        dir.join("ground.svg"),
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"240\" height=\"140\">\
         <rect width=\"240\" height=\"140\" fill=\"#f4f1ea\" stroke=\"#444\" stroke-width=\"4\"/></svg>",
    )
    .unwrap();
    let Some(browser) = browser() else { return };
    let server = serve("floors", &["--site", site.to_str().unwrap()]);
    let tab = open_dashboard(&browser, &server, "tester");
    wait_for(
        &tab,
        "document.getElementById('floor-select').options.length === 3",
        Duration::from_secs(20),
        "the floors listed",
    );

    // one tag on each floor (3-D fixes), posted with the write token
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64();
    let mut lines = String::new();
    for k in 0..8 {
        let t = now - 4.0 + 0.5 * f64::from(k);
        for (tag, position) in [("down", "[4.0,4.0,1.0]"), ("up", "[14.0,4.0,5.0]")] {
            lines.push_str(&format!(
                "{{\"t\":{t},\"tag\":\"{tag}\",\"kind\":\"fix\",\"position_m\":{position},\
                 \"covariance_m2\":[0.04,0,0,0,0.04,0,0,0,0.04]}}\n"
            ));
        }
    }
    let body = serde_json::to_string(&lines).unwrap();
    let posted = eval(
        &tab,
        &format!(
            "fetch('/api/v1/measurements', {{ method: 'POST', headers: {{ Authorization: 'Bearer {WRITE}' }}, \
             body: {body} }}).then(r => r.status)"
        ),
    );
    assert_eq!(posted, 200);
    wait_for(
        &tab,
        "window.rtls.liveTags.size === 2",
        Duration::from_secs(20),
        "both tags on screen",
    );
    // the text count follows new tags at once, not only at the 5 s reconciliation
    wait_for(
        &tab,
        "document.getElementById('live-count').dataset.count === '2'",
        Duration::from_secs(2),
        "the text count of live tags",
    );
    let shown = |floor: &str| {
        eval(
            &tab,
            &format!(
                "(() => {{ const s = document.getElementById('floor-select'); s.value = '{floor}'; \
                 s.dispatchEvent(new Event('change')); \
                 return {{ tags: window.rtls.map.visibleCount(), zones: window.rtls.map.zoneLayer.getLayers().map(l => l.zoneId), \
                          plans: [...document.querySelectorAll('img.leaflet-image-layer')].map(i => i.src.startsWith('blob:') && i.complete && i.naturalWidth) }}; }})()"
            ),
        )
    };
    let all = shown("");
    assert_eq!(all["tags"], 2, "{all}");
    // the ground floor's plan image under the map (fetched with the read token), none upstairs
    wait_for(
        &tab,
        "window.rtls.map.plans.size === 1",
        Duration::from_secs(10),
        "the ground floor's plan loaded",
    );
    let ground = shown("ground");
    assert_eq!(ground["tags"], 1, "{ground}");
    assert_eq!(ground["zones"], serde_json::json!(["dock"]), "{ground}");
    // a blob: image of the ground floor's plan, decoded at its 240 px width
    wait_until(
        &tab,
        "[...document.querySelectorAll('img.leaflet-image-layer')].map(i => i.src.startsWith('blob:') && i.complete && i.naturalWidth)",
        |v| v == &serde_json::json!([240]),
        Duration::from_secs(10),
        "the ground floor's plan drawn",
    );
    screenshot(&tab, "dashboard-floors");
    let mezzanine = shown("mezzanine");
    assert_eq!(mezzanine["tags"], 1, "{mezzanine}");
    assert_eq!(mezzanine["zones"], serde_json::json!(["gallery"]), "{mezzanine}");
    assert_eq!(
        mezzanine["plans"],
        serde_json::json!([]),
        "no plan upstairs: {mezzanine}"
    );
}
