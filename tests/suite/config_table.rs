//! Every configuration key, set to out-of-range or ill-typed values, gives
//! one clear error naming that key; none panics. The keys come from the
//! default configuration itself, so keys added later are covered too.

use stature::config::Config;

/// Keys where the "huge" probe is legitimately in range.
const HUGE_IS_VALID: &[&str] = &["run.frames", "track.seed", "calibrate.seed", "measure.seed"];
/// Keys where the "negative" probe is legitimately in range (none so far).
const NEGATIVE_IS_VALID: &[&str] = &[];

fn leaves(prefix: &str, v: &toml::Value, out: &mut Vec<(String, toml::Value)>) {
    match v {
        toml::Value::Table(t) => {
            for (k, v) in t {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                leaves(&key, v, out);
            }
        }
        other => out.push((prefix.to_string(), other.clone())),
    }
}

fn document(key: &str, value: &str) -> String {
    let (table, leaf) = key.rsplit_once('.').expect("every key lives in a section");
    format!("[{table}]\n{leaf} = {value}\n")
}

#[test]
fn every_key_refuses_bad_values_by_name() {
    let defaults = toml::Value::try_from(Config::default()).unwrap();
    let mut keys = Vec::new();
    leaves("", &defaults, &mut keys);
    assert!(keys.len() >= 8, "{keys:?}");
    let mut probes = 0;
    for (key, default) in &keys {
        let leaf = key.rsplit('.').next().unwrap();
        let mut bad: Vec<String> = vec!["\"not-a-value\"".into(), "[1, 2]".into()];
        match default {
            toml::Value::Integer(_) => {
                if !NEGATIVE_IS_VALID.contains(&key.as_str()) {
                    bad.push("-1".into());
                }
                if !HUGE_IS_VALID.contains(&key.as_str()) {
                    bad.push("1000000000000000".into());
                }
                bad.push("1.5".into());
            }
            toml::Value::Float(_) => {
                if !NEGATIVE_IS_VALID.contains(&key.as_str()) {
                    bad.push("-1e9".into());
                }
                if !HUGE_IS_VALID.contains(&key.as_str()) {
                    bad.push("1e15".into());
                }
                bad.push("nan".into());
            }
            toml::Value::Boolean(_) => bad.push("3".into()),
            toml::Value::String(s) if s.is_empty() => bad.retain(|b| b != "\"not-a-value\""),
            toml::Value::String(_) => {}
            toml::Value::Array(_) => bad = vec!["7".into(), "[\"tcp:1.2.3.4:5\"]".into()],
            _ => {}
        }
        for value in bad {
            // A string is a valid value for free-form string keys (paths, URIs checked at open).
            if matches!(default, toml::Value::String(_)) && value.starts_with('"') {
                continue;
            }
            probes += 1;
            let doc = document(key, &value);
            let result = std::panic::catch_unwind(|| Config::from_toml(&doc));
            let err = match result {
                Err(_) => panic!("{key} = {value}: panicked"),
                Ok(Ok(_)) => panic!("{key} = {value}: accepted"),
                Ok(Err(e)) => e.to_string(),
            };
            assert!(
                err.contains(leaf),
                "{key} = {value}: error does not name the key: {err}"
            );
            assert!(
                !err.contains('\n'),
                "{key} = {value}: error is not one line: {err}"
            );
        }
    }
    assert!(probes >= 20, "only {probes} probes");
}
