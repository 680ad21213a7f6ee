//! Helpers the workflow and merge tests share.

use serde_json::Value;

/// `value` without its timing fields and the folders a run was given.
pub fn numbers(value: &Value) -> Value {
    const LEFT_OUT: [&str; 7] = [
        "seconds",
        "ms_per_step",
        "cached",
        "wall",
        "cache_dir",
        "meshes",
        "fem_over",
    ];
    match value {
        Value::Object(map) => Value::Object(
            map.iter()
                .filter(|(k, _)| !LEFT_OUT.iter().any(|t| k.contains(t)))
                .map(|(k, v)| (k.clone(), numbers(v)))
                .collect(),
        ),
        Value::Array(items) => Value::Array(items.iter().map(numbers).collect()),
        other => other.clone(),
    }
}
