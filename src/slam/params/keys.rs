//! [`SlamParams`] by key: each value named `section.field` after the structs' own field
//! names (`icp.dist_m`, `icp.pyramid.radius_px`, `fusion.unstable_removal.every_frames`),
//! and each optional section switched by `section.enabled` (`loop_closure.enabled`). The
//! structs of `params` are the schema: a value is set by its key
//! ([`SlamParams::with_keys`]) from the command line's flags, parameter files and batch
//! manifests alike (`cli::pipeline_args` names the flag of each key), so a new field is a
//! new key with nothing else to write.
//!
//! Not the file format of `metrics.json` (which serialises [`SlamParams`] itself, an off
//! section as `null`), though the names are the same.

use std::collections::BTreeSet;

use serde::de::DeserializeOwned;
use serde::Serialize;

use super::{PoseSource, Profile, SlamParams, ValidParams};
use crate::{Error, Result};

/// The sections, each a table of keys (`icp` holds `icp.pyramid`, `fusion` holds
/// `fusion.unstable_removal`).
pub const KEY_SECTIONS: [&str; 8] = [
    "input",
    "normals",
    "bilateral",
    "icp",
    "fusion",
    "health",
    "relocalisation",
    "loop_closure",
];

/// The sections that may be off (`None` in [`SlamParams`]), each with an `enabled` key.
pub const OPTIONAL_SECTIONS: [&str; 5] = [
    "bilateral",
    "fusion.unstable_removal",
    "health",
    "relocalisation",
    "loop_closure",
];

/// A value by key, as [`SlamParams::with_keys`] takes it: `("icp.dist_m", 0.08)`.
pub type Key = (String, toml::Value);

impl SlamParams {
    /// Every key and its value: a table per section, nested as the structs are; an
    /// optional section that is off holds its type's defaults and `enabled = false`. The
    /// profile and the pose source are not keys.
    pub fn to_keys(&self) -> toml::Table {
        let mut t = toml::Table::try_from(self).expect("parameters are TOML");
        t.remove("profile");
        t.remove("poses");
        put_section(&mut t, "bilateral", &self.bilateral);
        put_section(
            &mut t,
            "fusion.unstable_removal",
            &self.fusion.unstable_removal,
        );
        put_section(&mut t, "health", &self.health);
        put_section(&mut t, "relocalisation", &self.relocalisation);
        put_section(&mut t, "loop_closure", &self.loop_closure);
        t
    }

    /// The parameters that [`SlamParams::to_keys`] made `t` from (with `profile` and
    /// `poses`); the error says what does not fit.
    fn from_keys(
        profile: Profile,
        poses: PoseSource,
        mut t: toml::Table,
    ) -> std::result::Result<SlamParams, String> {
        let bilateral = take_section(&mut t, "bilateral")?;
        let removal = take_section(&mut t, "fusion.unstable_removal")?;
        let health = take_section(&mut t, "health")?;
        let relocalisation = take_section(&mut t, "relocalisation")?;
        let loop_closure = take_section(&mut t, "loop_closure")?;
        t.insert("profile".into(), value_of(&profile));
        t.insert("poses".into(), value_of(&poses));
        let mut p: SlamParams = t.try_into().map_err(|e: toml::de::Error| e.to_string())?;
        p.bilateral = bilateral;
        p.fusion.unstable_removal = removal;
        p.health = health;
        p.relocalisation = relocalisation;
        p.loop_closure = loop_closure;
        Ok(p)
    }

    /// The values of `profile` with each of `keys` set in order (a later one wins),
    /// validated ([`SlamParams::validate`], the one time these parameters are checked).
    /// Setting a value of an optional section that is off turns it on (with its defaults
    /// elsewhere) unless the section's `enabled` is set too;
    /// `fusion.unstable_removal.stable_weight = 0` turns the removal off; loop closure is
    /// off without the keyframe database (`health` and `relocalisation`) unless
    /// `loop_closure` is set, in which case [`SlamParams::validate`] refuses it. Errors
    /// ([`Error::Argument`]) name the key in backquotes.
    ///
    /// The keys are set in one table of the profile's values ([`SlamParams::to_keys`]),
    /// which becomes parameters once, at the end; only when that fails are the keys set
    /// again one at a time to name the first one refused (`first_refused`).
    pub fn with_keys(profile: Profile, poses: PoseSource, keys: &[Key]) -> Result<ValidParams> {
        let mut t = SlamParams::profile(profile).to_keys();
        let (mut switched, mut touched) = (BTreeSet::new(), BTreeSet::new());
        for (key, value) in keys {
            if let Err(e) = set_key(&mut t, key, value) {
                return Err(first_refused(profile, poses, keys).unwrap_or(e));
            }
            let (section, field) = key.rsplit_once('.').expect("set_key checked the key");
            if field == "enabled" {
                switched.insert(section);
            } else {
                touched.insert(section);
            }
        }
        for section in OPTIONAL_SECTIONS {
            if touched.contains(section) && !switched.contains(section) {
                set_enabled(&mut t, section, true);
            }
        }
        if is_zero(&lookup(&t, "fusion.unstable_removal.stable_weight")) {
            set_enabled(&mut t, "fusion.unstable_removal", false);
        }
        let database = enabled(&t, "health") && enabled(&t, "relocalisation");
        let asked = switched.contains("loop_closure") || touched.contains("loop_closure");
        if !database && !asked {
            set_enabled(&mut t, "loop_closure", false);
        }
        if let Some(e) = photometric_without_rgbd(&t, keys) {
            return Err(e);
        }
        match SlamParams::from_keys(profile, poses, t) {
            Ok(p) => p.validate(),
            Err(why) => Err(first_refused(profile, poses, keys).unwrap_or(Error::Argument(why))),
        }
    }

    /// Checks that `key` is a key and `value` one its field takes, as
    /// [`SlamParams::with_keys`] does (the ranges are [`SlamParams::validate`]'s).
    pub fn check_key(key: &str, value: &toml::Value) -> Result<()> {
        let mut t = SlamParams::default().to_keys();
        set_key(&mut t, key, value)?;
        match SlamParams::from_keys(Profile::Robust, PoseSource::Track, t) {
            Ok(_) => Ok(()),
            Err(why) => Err(Error::Argument(format!("`{key}` = {value}: {why}"))),
        }
    }

    /// The value of `key` (`icp.dist_m`), `None` for a key that is not one.
    pub fn get_key(&self, key: &str) -> Option<toml::Value> {
        lookup(&self.to_keys(), key)
    }

    /// Every key, sorted: `section.field` for each value of [`SlamParams::to_keys`].
    pub fn keys() -> Vec<String> {
        fn walk(prefix: &str, t: &toml::Table, out: &mut Vec<String>) {
            for (name, v) in t {
                let key = format!("{prefix}{name}");
                match v {
                    toml::Value::Table(inner) => walk(&format!("{key}."), inner, out),
                    _ => out.push(key),
                }
            }
        }
        let mut out = Vec::new();
        walk("", &SlamParams::default().to_keys(), &mut out);
        out.sort();
        out
    }
}

/// The first of `keys` that its field refuses, set in order on `profile`'s values (each
/// value alone, before the rules between sections): the error that names the key, for
/// [`SlamParams::with_keys`]'s failures. `None` when each is taken alone (the rules
/// between sections, or the values together, are what fails).
fn first_refused(profile: Profile, poses: PoseSource, keys: &[Key]) -> Option<Error> {
    let mut t = SlamParams::profile(profile).to_keys();
    for (key, value) in keys {
        if let Err(e) = set_key(&mut t, key, value) {
            return Some(e);
        }
        if let Err(why) = SlamParams::from_keys(profile, poses, t.clone()) {
            return Some(Error::Argument(format!("`{key}` = {value}: {why}")));
        }
    }
    None
}

fn value_of<T: Serialize>(v: &T) -> toml::Value {
    toml::Value::try_from(v).expect("parameters are TOML")
}

/// The table at `path` (`fusion.unstable_removal`) inside `t`.
fn table_mut<'a>(t: &'a mut toml::Table, path: &str) -> Option<&'a mut toml::Table> {
    path.split('.')
        .try_fold(t, |t, name| t.get_mut(name)?.as_table_mut())
}

/// The value at `key`, if any.
fn lookup(t: &toml::Table, key: &str) -> Option<toml::Value> {
    let (path, field) = key.rsplit_once('.')?;
    let t = path
        .split('.')
        .try_fold(t, |t, name| t.get(name)?.as_table())?;
    t.get(field).cloned()
}

/// The photometric keys do something only with RGB-D tracking: one set in `keys` while
/// `icp.tracking` (in `t`, after every key) is not `rgbd` is refused, naming both keys (an
/// option that does nothing in the current mode is refused, not silently ignored).
fn photometric_without_rgbd(t: &toml::Table, keys: &[Key]) -> Option<Error> {
    let rgbd = lookup(t, "icp.tracking").and_then(|v| v.as_str().map(String::from));
    if rgbd.as_deref() == Some("rgbd") {
        return None;
    }
    let (key, _) = keys
        .iter()
        .find(|(k, _)| k == "icp.photometric_weight" || k == "icp.photometric_levels")?;
    Some(Error::Argument(format!(
        "`{key}` does nothing unless `icp.tracking` is \"rgbd\" (the photometric term is \
         part of RGB-D tracking only; here tracking is {}): set `icp.tracking` to \"rgbd\", \
         or leave `{key}` out",
        rgbd.as_deref().unwrap_or("geometric")
    )))
}

fn is_zero(v: &Option<toml::Value>) -> bool {
    matches!(v, Some(toml::Value::Float(f)) if *f == 0.0)
}

fn enabled(t: &toml::Table, section: &str) -> bool {
    lookup(t, &format!("{section}.enabled")).and_then(|v| v.as_bool()) == Some(true)
}

fn set_enabled(t: &mut toml::Table, section: &str, on: bool) {
    let s = table_mut(t, section).expect("an optional section");
    s.insert("enabled".into(), toml::Value::Boolean(on));
}

/// Writes an optional section into `t` at `path`: its values (its type's defaults when
/// off) and `enabled`.
fn put_section<T: Serialize + Default + Clone>(t: &mut toml::Table, path: &str, v: &Option<T>) {
    let mut section = toml::Table::try_from(v.clone().unwrap_or_default())
        .expect("a settings struct is a TOML table");
    section.insert("enabled".into(), toml::Value::Boolean(v.is_some()));
    let (parent, name) = match path.rsplit_once('.') {
        Some((parent, name)) => (table_mut(t, parent).expect("a section"), name),
        None => (t, path),
    };
    parent.insert(name.into(), toml::Value::Table(section));
}

/// Takes the section at `path` out of `t`: `Some` of its values when enabled.
fn take_section<T: DeserializeOwned>(
    t: &mut toml::Table,
    path: &str,
) -> std::result::Result<Option<T>, String> {
    let (parent, name) = match path.rsplit_once('.') {
        Some((parent, name)) => (table_mut(t, parent).expect("a section"), name),
        None => (&mut *t, path),
    };
    let Some(toml::Value::Table(mut section)) = parent.remove(name) else {
        panic!("to_keys wrote the section {path}");
    };
    let on = section.remove("enabled").and_then(|v| v.as_bool());
    match on {
        Some(true) => section
            .try_into()
            .map(Some)
            .map_err(|e: toml::de::Error| format!("`{path}`: {e}")),
        _ => Ok(None),
    }
}

/// Sets the existing value at `key` to `value`, of the same TOML type (an integer where a
/// float is becomes that float). An unknown key or a value of another type is an error
/// naming the key.
fn set_key(t: &mut toml::Table, key: &str, value: &toml::Value) -> Result<()> {
    let unknown = || {
        Error::Argument(format!(
            "unknown key `{key}`; the keys are: {}",
            SlamParams::keys().join(", ")
        ))
    };
    let (path, field) = key.rsplit_once('.').ok_or_else(unknown)?;
    let section = table_mut(t, path).ok_or_else(unknown)?;
    let slot = section.get_mut(field).ok_or_else(unknown)?;
    let value = match (&*slot, value) {
        (toml::Value::Table(_), _) => return Err(unknown()),
        (toml::Value::Float(_), toml::Value::Integer(i)) => toml::Value::Float(*i as f64),
        (old, new) if old.same_type(new) => new.clone(),
        (old, new) => {
            return Err(Error::Argument(format!(
                "`{key}` wants a {}, not {new}",
                old.type_str()
            )))
        }
    };
    *slot = value;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every profile's values survive the key view unchanged.
    #[test]
    fn keys_read_back_as_the_same_parameters() {
        for profile in [Profile::Assignment, Profile::Robust] {
            let p = SlamParams::profile(profile);
            let back = SlamParams::from_keys(profile, PoseSource::Track, p.to_keys()).unwrap();
            assert_eq!(back, p, "{profile:?}");
            assert_eq!(
                *SlamParams::with_keys(profile, PoseSource::Track, &[]).unwrap(),
                p
            );
        }
    }

    fn set(profile: Profile, keys: &[(&str, toml::Value)]) -> Result<ValidParams> {
        let keys: Vec<Key> = keys
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect();
        SlamParams::with_keys(profile, PoseSource::Track, &keys)
    }

    /// Every key (but the `enabled` switches) set to another value of its type reaches its
    /// field: the parameters read back through the key view hold it.
    #[test]
    fn every_key_reaches_its_field() {
        let base = SlamParams::default();
        let base_keys = base.to_keys();
        for key in SlamParams::keys() {
            if key.ends_with(".enabled") {
                continue;
            }
            let old = lookup(&base_keys, &key).unwrap();
            // Another valid value of the same type: a little larger (a few values have an
            // upper bound of 1, or must stay below max_depth_m's 10).
            let new = match &old {
                toml::Value::Float(f) => toml::Value::Float(if *f > 0.0 && *f < 1.0 {
                    f * 0.5
                } else {
                    f + 0.5
                }),
                toml::Value::Integer(i) => toml::Value::Integer(i + 1),
                toml::Value::Boolean(b) => toml::Value::Boolean(!b),
                // The other variant of each enum key.
                toml::Value::String(_) if key == "icp.tracking" => {
                    toml::Value::String("rgbd".into())
                }
                toml::Value::String(_) => toml::Value::String("projective".into()),
                // A pyramid level of the robust profile's three.
                toml::Value::Array(_) if key == "icp.photometric_levels" => {
                    toml::Value::Array(vec![toml::Value::Integer(1)])
                }
                toml::Value::Array(_) => toml::Value::Array(vec![toml::Value::Integer(7)]),
                other => panic!("{key}: {other}"),
            };
            assert_ne!(old, new, "{key}");
            // The photometric keys are refused without RGB-D tracking (issue 46).
            let mut keys = vec![(key.as_str(), new.clone())];
            if key.starts_with("icp.photometric_") {
                keys.push(("icp.tracking", toml::Value::String("rgbd".into())));
            }
            let p = set(Profile::Robust, &keys).unwrap_or_else(|e| panic!("{key} = {new}: {e}"));
            let got = lookup(&p.to_keys(), &key).unwrap();
            // f32 fields hold the value rounded to f32.
            let same = match (&got, &new) {
                (toml::Value::Float(a), toml::Value::Float(b)) => (a - b).abs() <= 1e-6 * b.abs(),
                (a, b) => a == b,
            };
            assert!(same, "{key}: set {new}, read {got}");
        }
    }

    /// A photometric key without RGB-D tracking does nothing: refused, naming both keys
    /// (issue 46: `--photometric-weight` was accepted without `--tracking rgbd`).
    #[test]
    fn photometric_keys_need_rgbd_tracking() {
        use toml::Value::{Float, String};
        let weight = ("icp.photometric_weight", Float(0.5));
        let e = set(Profile::Robust, std::slice::from_ref(&weight))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`icp.photometric_weight` does nothing unless `icp.tracking`"),
            "{e}"
        );
        let rgbd = ("icp.tracking", String("rgbd".into()));
        assert!(set(Profile::Robust, &[weight, rgbd]).is_ok());
    }

    /// The rules between sections, as the command line has always had them.
    #[test]
    fn section_rules() {
        use toml::Value::{Boolean, Float, Integer};
        let a = Profile::Assignment;
        // A value of a section that is off turns it on, with the defaults elsewhere.
        let p = set(a, &[("fusion.unstable_removal.max_age_frames", Integer(9))]).unwrap();
        let r = p.fusion.unstable_removal.unwrap();
        assert_eq!((r.max_age_frames, r.every_frames), (9, 10));
        // ... but not against its `enabled`.
        let p = set(
            Profile::Robust,
            &[
                ("health.enabled", Boolean(false)),
                ("health.min_inlier_fraction", Float(0.2)),
            ],
        )
        .unwrap();
        assert_eq!(p.health, None);
        // A stable weight of 0 is the removal off.
        let p = set(
            Profile::Robust,
            &[("fusion.unstable_removal.stable_weight", Integer(0))],
        )
        .unwrap();
        assert_eq!(p.fusion.unstable_removal, None);
        // Without the keyframe database loop closure is off, and refused when asked for.
        let p = set(
            Profile::Robust,
            &[("relocalisation.enabled", Boolean(false))],
        )
        .unwrap();
        assert_eq!(p.loop_closure, None);
        let err = set(
            Profile::Robust,
            &[
                ("relocalisation.enabled", Boolean(false)),
                ("loop_closure.enabled", Boolean(true)),
            ],
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("`loop_closure.enabled`"), "{err}");
        let p = set(a, &[("loop_closure.enabled", Boolean(true))]).unwrap();
        assert_eq!(p.loop_closure, Some(Default::default()));
    }

    #[test]
    fn unknown_keys_and_wrong_types_name_the_key() {
        use toml::Value::{Float, Integer, String};
        for (key, value, needle) in [
            ("icp.dits_m", Float(0.1), "unknown key `icp.dits_m`"),
            ("icp", Float(0.1), "unknown key `icp`"),
            ("icp.pyramid", Float(0.1), "unknown key `icp.pyramid`"),
            ("profile", String("robust".into()), "unknown key `profile`"),
            (
                "icp.dist_m",
                String("far".into()),
                "`icp.dist_m` wants a float",
            ),
            ("input.downsample", Integer(-2), "`input.downsample`"),
            (
                "fusion.association",
                String("nearest".into()),
                "`fusion.association`",
            ),
        ] {
            let err = set(Profile::Robust, &[(key, value)])
                .unwrap_err()
                .to_string();
            assert!(err.contains(needle), "{key}: {err}");
        }
    }
}

#[cfg(test)]
mod help_tests {
    use clap::ValueEnum;

    use super::*;

    /// The profiles' `--profile` help states values in words (the command line cannot show
    /// intra-doc links); they must stay the profile's own.
    #[test]
    fn the_robust_profiles_help_states_its_values() {
        let help = Profile::Robust
            .to_possible_value()
            .and_then(|v| v.get_help().map(|h| h.to_string()))
            .expect("the robust profile has a help text");
        assert!(!help.contains("[`"), "intra-doc link in the help: {help}");
        let p = SlamParams::profile(Profile::Robust);
        let iters: Vec<String> = p.icp.level_iters.iter().map(|n| n.to_string()).collect();
        let stated = [
            format!("({}, {} and {} iterations)", iters[0], iters[1], iters[2]),
            format!(
                "{:.2} m / {} degree association",
                p.icp.dist_m, p.icp.normal_deg
            ),
            format!("({} m / {} degrees)", p.fusion.dist_m, p.fusion.normal_deg),
        ];
        for s in stated {
            assert!(help.contains(&s), "help lacks `{s}`: {help}");
        }
    }
}
