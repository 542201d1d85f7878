//! `--set KEY=VALUE` and `--size WxH` (SPEC §16): scene-file keys set from the command line,
//! checked exactly as the file's own keys are.
//!
//! The file is parsed as written first, so its own errors name its own lines. Then each setting
//! is applied, in order, to the file's TOML document (`light.0.position` is the `position` of
//! the first `[[light]]`; a missing table on the way is created), and the document is parsed
//! again after each one: an error then can only come from that setting, and is reported as
//! `invalid setting --set KEY=VALUE: …` without the rewritten document's line numbers.

use std::path::Path;
use std::str::FromStr;

use toml::{Table, Value};

use super::Scene;
use super::file::{MAX_IMAGE_SIDE, parse};
use crate::error::SceneError;

/// One `--set KEY=VALUE`: a dotted key path and a TOML value.
#[derive(Clone, Debug, PartialEq)]
pub struct Setting {
    /// The dotted path as given (`render.max_depth`, `light.0.position`).
    pub key: String,
    /// The value, parsed as TOML (`3`, `[1, 2, 3]`, `"room.obj"`).
    pub value: Value,
    /// The argument as given, for messages.
    pub arg: String,
}

impl FromStr for Setting {
    type Err = SceneError;

    /// Parses `KEY=VALUE`; VALUE is a TOML value (strings in double quotes).
    fn from_str(arg: &str) -> Result<Setting, SceneError> {
        let fail = |message: String| SceneError::Setting {
            key: format!("--set {arg}"),
            message,
        };
        let (key, value) = arg
            .split_once('=')
            .ok_or_else(|| fail("expected KEY=VALUE".into()))?;
        let key = key.trim();
        if key.is_empty() || key.split('.').any(str::is_empty) {
            return Err(fail(format!("{key:?} is not a dotted key path")));
        }
        let value = format!("v = {value}")
            .parse::<Table>()
            .ok()
            .and_then(|mut t| t.remove("v"))
            .ok_or_else(|| {
                fail(format!(
                    "{value:?} is not a TOML value (quote strings: --set '{key}=\"…\"')"
                ))
            })?;
        Ok(Setting {
            key: key.to_owned(),
            value,
            arg: format!("--set {arg}"),
        })
    }
}

impl Setting {
    /// `--size WxH` as the two settings `image.width` and `image.height`.
    pub fn size(arg: &str) -> Result<[Setting; 2], SceneError> {
        let fail = |message: String| SceneError::Setting {
            key: format!("--size {arg}"),
            message,
        };
        let (w, h) = arg
            .split_once(['x', 'X'])
            .ok_or_else(|| fail("expected WIDTHxHEIGHT, e.g. 640x480".into()))?;
        let side = |s: &str| -> Result<i64, SceneError> {
            s.parse::<u32>()
                .ok()
                .filter(|n| (1..=MAX_IMAGE_SIDE).contains(n))
                .map(i64::from)
                .ok_or_else(|| fail(format!("{s:?} is not a side in 1..={MAX_IMAGE_SIDE}")))
        };
        let (w, h) = (side(w)?, side(h)?);
        let set = |key: &str, n: i64| Setting {
            key: key.to_owned(),
            value: Value::Integer(n),
            arg: format!("--size {arg}"),
        };
        Ok([set("image.width", w), set("image.height", h)])
    }

    /// Sets this key in `doc`, creating missing tables on the way; a list on the way (an array
    /// of tables such as `[[light]]`) takes an index as its next part.
    fn apply(&self, doc: &mut Table) -> Result<(), String> {
        let parts: Vec<&str> = self.key.split('.').collect();
        let mut table = doc;
        let mut at = String::new();
        let mut i = 0;
        loop {
            let part = parts[i];
            let name = if at.is_empty() {
                part.to_owned()
            } else {
                format!("{at}.{part}")
            };
            if i + 1 == parts.len() {
                table.insert(part.to_owned(), self.value.clone());
                return Ok(());
            }
            let entry = table
                .entry(part.to_owned())
                .or_insert_with(|| Value::Table(Table::new()));
            table = match entry {
                Value::Table(t) => {
                    i += 1;
                    t
                }
                Value::Array(items) => {
                    let n: usize = parts[i + 1]
                        .parse()
                        .map_err(|_| format!("{name} is a list: the next part must be an index"))?;
                    if i + 2 == parts.len() {
                        return Err(format!("{name}.{n} is a whole entry: set one of its keys"));
                    }
                    let count = items.len();
                    i += 2;
                    match items.get_mut(n) {
                        Some(Value::Table(t)) => t,
                        Some(_) => return Err(format!("{name}.{n} is not a table")),
                        None => return Err(format!("{name}.{n}: the scene has {count}")),
                    }
                }
                _ => return Err(format!("{name} is not a table")),
            };
            at = parts[..i].join(".");
        }
    }
}

/// The image size `settings` ask for (`image.width`, `image.height`, each `None` when not set),
/// for `what`, a scene without a file (a built-in or a bare mesh), to which no other key applies.
pub(crate) fn image_size(
    settings: &[Setting],
    what: &str,
) -> Result<(Option<u32>, Option<u32>), SceneError> {
    let mut size = (None, None);
    for s in settings {
        let fail = |message: String| SceneError::Setting {
            key: s.arg.clone(),
            message,
        };
        let side = match s.key.as_str() {
            "image.width" => &mut size.0,
            "image.height" => &mut size.1,
            _ => {
                return Err(fail(format!(
                    "{what} is not a scene file: only --size (image.width, image.height) \
                     applies to it"
                )));
            }
        };
        let n = s
            .value
            .as_integer()
            .and_then(|n| u32::try_from(n).ok())
            .filter(|n| (1..=MAX_IMAGE_SIDE).contains(n))
            .ok_or_else(|| fail(format!("must be an integer in 1..={MAX_IMAGE_SIDE}")))?;
        *side = Some(n);
    }
    Ok(size)
}

/// The scene file at `path` with `settings` applied in order; see the module docs.
pub(crate) fn load_with(path: &Path, settings: &[Setting]) -> Result<Scene, SceneError> {
    let text = super::file::read(path)?;
    let mut scene = parse(&text, path)?;
    if settings.is_empty() {
        return Ok(scene);
    }
    let mut doc: Table = text
        .parse()
        .map_err(|e: toml::de::Error| SceneError::Setting {
            key: path.display().to_string(),
            message: e.message().to_owned(),
        })?;
    for s in settings {
        let fail = |message: String| SceneError::Setting {
            key: s.arg.clone(),
            message,
        };
        s.apply(&mut doc).map_err(fail)?;
        let rewritten = toml::to_string(&doc).map_err(|e| fail(e.to_string()))?;
        scene = parse(&rewritten, path).map_err(|e| match e {
            SceneError::Invalid { key, message, .. } => fail(format!("{key}: {message}")),
            other => fail(other.to_string()),
        })?;
    }
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_parse_key_paths_and_toml_values() {
        let s: Setting = "light.0.position=[1, 2, 3]".parse().unwrap();
        assert_eq!(s.key, "light.0.position");
        assert_eq!(s.value, "v = [1, 2, 3]".parse::<Table>().unwrap()["v"]);
        let s: Setting = "mesh.0.path=\"a b.obj\"".parse().unwrap();
        assert_eq!(s.value, Value::String("a b.obj".into()));
        for bad in [
            "noequals",
            "=3",
            "a..b=1",
            "render.max_depth=",
            "mesh.0.path=a b",
        ] {
            let e = bad.parse::<Setting>().unwrap_err().to_string();
            assert!(
                e.starts_with(&format!("invalid setting --set {bad}: ")),
                "{e}"
            );
        }
    }

    #[test]
    fn sizes_are_two_settings_within_the_limits() {
        let [w, h] = Setting::size("640x480").unwrap();
        assert_eq!(
            (w.key.as_str(), &w.value),
            ("image.width", &Value::Integer(640))
        );
        assert_eq!(
            (h.key.as_str(), &h.value),
            ("image.height", &Value::Integer(480))
        );
        for bad in ["640", "0x10", "10x40000", "ax4", "-1x4"] {
            assert!(Setting::size(bad).is_err(), "{bad}");
        }
    }
}
