//! The configuration's tests: defaults, validation, and the documented example file.
use super::*;

#[test]
fn an_unknown_key_and_a_bad_value_are_named_with_their_line() {
    let dir = std::env::temp_dir().join(format!("rtls-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("server.toml");
    std::fs::write(&path, "[server]\nhttp = \"127.0.0.1:9000\"\nretention = 5\n").unwrap();
    let error = ServerConfig::from_file(&path).unwrap_err().to_string();
    assert!(error.contains("line 3") && error.contains("retention"), "{error}");
    std::fs::write(&path, "[server]\nretention_days = -1\n").unwrap();
    let error = ServerConfig::from_file(&path).unwrap_err().to_string();
    assert!(error.contains("server.retention_days"), "{error}");
    std::fs::write(&path, "[mqtt]\nmode = \"external\"\n").unwrap();
    let error = ServerConfig::from_file(&path).unwrap_err().to_string();
    assert!(error.contains("mqtt.url"), "{error}");
    std::fs::write(
        &path,
        "[server]\nhttp = \"127.0.0.1:9000\"\n[pipeline]\npartitions = 3\n",
    )
    .unwrap();
    let config = ServerConfig::from_file(&path).unwrap();
    assert_eq!(
        (
            config.server.http.port(),
            config.pipeline.partitions,
            config.server.retention_days
        ),
        (9000, 3, 92.0)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_cors_origin_with_a_path_or_without_a_scheme_is_refused_by_index() {
    for (origin, ok) in [
        ("https://ops.example.com", true),
        ("http://127.0.0.1:3000", true),
        ("*", true),
        ("ops.example.com", false),
        ("https://ops.example.com/", false),
    ] {
        let mut config = ServerConfig::default();
        config.server.cors_origins = vec!["https://a.example".into(), origin.into()];
        match config.validate() {
            Ok(()) => assert!(ok, "{origin} accepted"),
            Err(ConfigError::Invalid { field, .. }) => {
                assert!(!ok, "{origin} refused");
                assert_eq!(field, "server.cors_origins[1]");
            }
            Err(e) => panic!("{e}"),
        }
    }
}

#[test]
fn passwords_are_hidden_and_everything_else_kept() {
    assert_eq!(
        redact_password("mqtt://rtls:s3cret@broker:1883?client_id=a"),
        "mqtt://rtls:***@broker:1883?client_id=a"
    );
    assert_eq!(
        redact_password("postgres://rtls:secret@db:5432/rtls"),
        "postgres://rtls:***@db:5432/rtls"
    );
    assert_eq!(redact_password("mqtt://rtls@broker:1883"), "mqtt://rtls@broker:1883");
    assert_eq!(redact_password("mqtt://broker:1883/x@y:z"), "mqtt://broker:1883/x@y:z");
    assert_eq!(redact_password("sqlite:rtls.db"), "sqlite:rtls.db");
}

#[test]
fn the_documented_example_file_parses_to_the_defaults_it_documents() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/server.toml");
    let config = ServerConfig::from_file(&path).unwrap();
    let defaults = ServerConfig::default();
    assert_eq!(
        config.server.site.as_deref(),
        Some(std::path::Path::new("examples/site.toml"))
    );
    assert_eq!(
        (config.server.http, &config.server.db),
        (defaults.server.http, &defaults.server.db)
    );
    assert_eq!(config.mqtt, defaults.mqtt);
    assert_eq!(config.pipeline, defaults.pipeline);
    assert_eq!(config.server.retention_days, 92.0);
    assert!(config.webhooks.is_empty(), "the example's webhook is commented out");
}

/// The commented-out `header` table of `examples/server.toml` and the comment lines after it,
/// uncommented.
fn uncommented_example_table(header: &str) -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/server.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let start = text
        .find(&format!("# {header}"))
        .unwrap_or_else(|| panic!("a commented {header} example"));
    text[start..]
        .lines()
        .take_while(|line| line.starts_with('#'))
        .map(|line| line.strip_prefix("# ").unwrap_or(line))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The example's commented-out `[adapters.generic]` table, uncommented: it parses, validates
/// and reads Quuppa's `locationTS` in milliseconds.
#[test]
fn the_documented_generic_adapter_table_parses_and_validates() {
    let table = uncommented_example_table("[adapters.generic]");
    let config: ServerConfig = toml::from_str(&table).unwrap_or_else(|e| panic!("{e}\n{table}"));
    config.validate().unwrap();
    let generic = config.adapters.generic.expect("the generic adapter");
    assert_eq!(generic.time_unit, crate::adapters::TimeUnit::Ms);
    assert_eq!(generic.z.as_deref(), Some("location.2"));
}

/// The example's commented-out `[adapters.zebra]` table, uncommented: every key is known, and
/// the values shown are the defaults (but for the hub); a hub that is not `HOST:PORT` is refused.
#[test]
fn the_documented_zebra_table_parses_with_the_defaults_it_documents() {
    let table = uncommented_example_table("[adapters.zebra]");
    let mut config: ServerConfig = toml::from_str(&table).unwrap_or_else(|e| panic!("{e}\n{table}"));
    config.validate().unwrap();
    let keys = table.lines().filter(|l| l.contains(" = ")).count();
    assert_eq!(keys, 5, "every key shown:\n{table}");
    assert_eq!(config.adapters.zebra.hub.as_deref(), Some("10.0.0.5:5117"));
    assert_eq!(
        config.adapters.zebra,
        crate::adapters::ZebraAdapter {
            hub: Some("10.0.0.5:5117".into()),
            ..crate::adapters::ZebraAdapter::default()
        }
    );
    config.adapters.zebra.hub = Some("10.0.0.5".into());
    let error = config.validate().unwrap_err().to_string();
    assert!(error.starts_with("config adapters.zebra: hub:"), "{error}");
}

/// The example's commented-out `[cluster]` table, uncommented: every key is known, and the
/// values shown are the defaults (but for the servers).
#[test]
fn the_documented_cluster_table_parses_with_the_defaults_it_documents() {
    let table = uncommented_example_table("[cluster]");
    let config: ServerConfig = toml::from_str(&table).unwrap_or_else(|e| panic!("{e}\n{table}"));
    let keys = table.lines().filter(|l| l.contains(" = ")).count();
    assert_eq!(keys, 10, "every key shown:\n{table}");
    assert_eq!(config.cluster.servers.len(), 3);
    assert_eq!(
        cluster::ClusterSection {
            servers: Vec::new(),
            ..config.cluster
        },
        cluster::ClusterSection::default()
    );
}

/// The example's commented-out `[[webhooks]]` table, uncommented: every key it shows is
/// known, and the values it shows are the defaults (but for url, name and the secret).
#[test]
fn the_documented_webhook_table_parses_with_the_defaults_it_documents() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/server.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let start = text.find("# [[webhooks]]").expect("a [[webhooks]] example");
    let table: String = text[start..]
        .lines()
        .take_while(|line| !line.trim().is_empty())
        .filter(|line| !line.starts_with("#  "))
        .map(|line| line.strip_prefix("# ").unwrap_or(line))
        .collect::<Vec<_>>()
        .join("\n");
    let mut config: ServerConfig = toml::from_str(&table).unwrap_or_else(|e| panic!("{e}\n{table}"));
    assert_eq!(config.webhooks.len(), 1);
    let webhook = &mut config.webhooks[0];
    let keys = table.lines().filter(|l| l.contains(" = ")).count();
    assert_eq!(keys, 9, "every key shown:\n{table}");
    assert_eq!(webhook.url, "https://ops.example.com/rtls/alarms");
    assert_eq!(webhook.name.as_deref(), Some("ops"));
    assert_eq!(
        webhook.events.clone().unwrap(),
        crate::webhooks::DEFAULT_EVENT_TYPES.map(String::from)
    );
    assert_eq!(
        (webhook.secret.as_deref(), webhook.secret_env.as_deref()),
        (Some("change-me"), Some("RTLS_WEBHOOK_SECRET"))
    );
    let defaults = WebhookSection::default();
    assert_eq!(
        (
            webhook.timeout_s,
            webhook.max_attempts,
            webhook.initial_backoff_s,
            webhook.max_backoff_s
        ),
        (
            defaults.timeout_s,
            defaults.max_attempts,
            defaults.initial_backoff_s,
            defaults.max_backoff_s
        )
    );
    // secret and secret_env are alternatives
    match config.validate() {
        Err(ConfigError::Invalid { field, .. }) => assert_eq!(field, "webhooks[0].secret"),
        other => panic!("{other:?}"),
    }
    config.webhooks[0].secret_env = None;
    config.validate().unwrap();
}

#[test]
fn a_bad_webhook_is_refused_naming_its_index_and_key() {
    let webhook = |url: &str| WebhookSection {
        url: url.into(),
        ..WebhookSection::default()
    };
    let field_of = |webhooks: Vec<WebhookSection>| {
        let config = ServerConfig {
            webhooks,
            ..ServerConfig::default()
        };
        match config.validate() {
            Ok(()) => "ok".to_string(),
            Err(ConfigError::Invalid { field, reason }) => {
                assert!(!reason.contains("t0ken"), "the URL's token is not repeated: {reason}");
                field
            }
            Err(e) => panic!("{e}"),
        }
    };
    let ok = webhook("https://a.example/hook");
    assert_eq!(field_of(vec![ok.clone(), webhook("http://127.0.0.1:9000/x")]), "ok");
    assert_eq!(
        field_of(vec![ok.clone(), webhook("ftp://b.example/t0ken")]),
        "webhooks[1].url"
    );
    assert_eq!(
        field_of(vec![ok.clone(), webhook("b.example/t0ken")]),
        "webhooks[1].url"
    );
    assert_eq!(field_of(vec![webhook("")]), "webhooks[0].url");
    // two webhooks to one host need names
    assert_eq!(
        field_of(vec![ok.clone(), webhook("https://a.example/other")]),
        "webhooks[1].name"
    );
    let named = WebhookSection {
        name: Some("second".into()),
        ..webhook("https://a.example/other")
    };
    assert_eq!(field_of(vec![ok.clone(), named]), "ok");
    let with = |f: &dyn Fn(&mut WebhookSection)| {
        let mut w = ok.clone();
        f(&mut w);
        field_of(vec![w])
    };
    assert_eq!(
        with(&|w| w.events = Some(vec!["lost".into(), "zone-exit".into()])),
        "webhooks[0].events[1]"
    );
    assert_eq!(with(&|w| w.events = Some(Vec::new())), "webhooks[0].events");
    assert_eq!(with(&|w| w.events = Some(vec!["model-switch".into()])), "ok");
    assert_eq!(with(&|w| w.timeout_s = 0.0), "webhooks[0].timeout_s");
    assert_eq!(with(&|w| w.max_attempts = 0), "webhooks[0].max_attempts");
    assert_eq!(
        with(&|w| w.initial_backoff_s = f64::NAN),
        "webhooks[0].initial_backoff_s"
    );
    assert_eq!(with(&|w| w.max_backoff_s = 0.5), "webhooks[0].max_backoff_s");
    assert_eq!(with(&|w| w.secret = Some(String::new())), "webhooks[0].secret");
    assert_eq!(
        with(&|w| w.secret_env = Some("RTLS_TEST_WEBHOOK_SECRET_THAT_IS_NOT_SET".into())),
        "webhooks[0].secret_env"
    );
    let secret = WebhookSection {
        secret: Some("s3cret-key".into()),
        ..ok.clone()
    };
    assert!(!format!("{secret:?}").contains("s3cret-key"), "Debug hides the secret");
    assert_eq!(ok.resolved_name(0).unwrap(), "a.example");
    assert_eq!(
        webhook("http://127.0.0.1:9000/x?token=t0ken").resolved_name(0).unwrap(),
        "127.0.0.1:9000"
    );
}

/// The example's commented-out `[udp]` table, uncommented: it parses and validates, a listener
/// for measurement lines and one for Quuppa's messages.
#[test]
fn the_documented_udp_table_parses_and_validates() {
    let table = uncommented_example_table("[udp]");
    let config: ServerConfig = toml::from_str(&table).unwrap_or_else(|e| panic!("{e}\n{table}"));
    config.validate().unwrap();
    let listeners = config.udp.listeners();
    assert_eq!(
        listeners,
        vec![
            (None, "0.0.0.0:9000".parse().unwrap()),
            (Some(crate::adapters::Vendor::Quuppa), "0.0.0.0:9001".parse().unwrap())
        ]
    );
}

/// The example's commented-out `[[nats_forward]]` table, uncommented: every key it shows is
/// known, and the values it shows are the defaults (but for url, name and the token's variable).
#[test]
fn the_documented_nats_forward_table_parses_with_the_defaults_it_documents() {
    let table = uncommented_example_table("[[nats_forward]]");
    let mut config: ServerConfig = toml::from_str(&table).unwrap_or_else(|e| panic!("{e}\n{table}"));
    let keys = table.lines().filter(|l| l.contains(" = ")).count();
    assert_eq!(keys, 5, "every key shown:\n{table}");
    assert_eq!(config.nats_forward.len(), 1);
    let forward = &mut config.nats_forward[0];
    assert_eq!(forward.token_env.as_deref(), Some("RTLS_NATS_TOKEN"));
    // the variable is not set here
    forward.token_env = None;
    validate_nats_forwards(&config.nats_forward).unwrap();
    let defaults = NatsForwardSection::default();
    let forward = &config.nats_forward[0];
    assert_eq!(
        (&forward.url, forward.name.as_deref()),
        (&"nats://127.0.0.1:4222".to_string(), Some("bus"))
    );
    assert_eq!(
        (&forward.subject_prefix, &forward.topics),
        (&defaults.subject_prefix, &defaults.topics)
    );
}
