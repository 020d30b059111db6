//! Driving headless chromium over the DevTools protocol, shared by the dashboard's browser tests
//! (`tests/dashboard_browser.rs`) and its benchmark (`examples/dashboard_bench.rs`).

use std::path::PathBuf;
use std::time::Duration;

use headless_chrome::protocol::cdp::Runtime;
use headless_chrome::{Browser, LaunchOptions, Tab};
use serde_json::Value;

/// Starts headless chromium from `path`: no sandbox (CI runs as root), a 1500 × 900 window,
/// and an idle timeout long enough for waits of minutes without a DevTools message.
///
/// # Errors
/// The launch's error, as text.
pub fn launch(path: PathBuf) -> Result<Browser, String> {
    let options = LaunchOptions::default_builder()
        .path(Some(path))
        .headless(true)
        .sandbox(false)
        .window_size(Some((1500, 900)))
        .idle_browser_timeout(Duration::from_secs(600))
        .build()
        .map_err(|e| e.to_string())?;
    Browser::new(options).map_err(|e| format!("chromium does not start: {e}"))
}

/// The value of a JavaScript expression in `tab`, a promise awaited, returned by value.
///
/// # Errors
/// The protocol's error, or the page's exception with its description.
pub fn eval(tab: &Tab, expression: &str) -> Result<Value, String> {
    let reply = tab
        .call_method(Runtime::Evaluate {
            expression: expression.to_string(),
            return_by_value: Some(true),
            generate_preview: None,
            silent: Some(false),
            await_promise: Some(true),
            include_command_line_api: None,
            user_gesture: Some(true),
            object_group: None,
            context_id: None,
            throw_on_side_effect: None,
            timeout: None,
            disable_breaks: None,
            repl_mode: None,
            allow_unsafe_eval_blocked_by_csp: None,
            unique_context_id: None,
            serialization_options: None,
        })
        .map_err(|e| format!("evaluating {expression}: {e}"))?;
    if let Some(exception) = reply.exception_details {
        return Err(format!(
            "evaluating {expression}: {} {:?}",
            exception.text,
            exception.exception.and_then(|e| e.description)
        ));
    }
    Ok(reply.result.value.unwrap_or(Value::Null))
}
