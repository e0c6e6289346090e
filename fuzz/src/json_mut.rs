//! Structure-aware mutation of JSON documents (the bake file's header and metadata, glTF).
//!
//! A random walk from the root picks a node: at each array or object it stops with a small
//! probability (mutating the container itself), else it descends into a random child. So every
//! level of the document is reached about equally often, however long its arrays are.

use serde_json::{Map, Number, Value};

use crate::mutate::Dice;

/// Integers on the boundaries readers care about: counts, indices, u32/i64/u64 limits, and the
/// glTF component types and buffer targets.
const INTS: [i128; 27] = [
    0,
    1,
    -1,
    2,
    3,
    4,
    7,
    8,
    16,
    255,
    256,
    4096,
    65535,
    65536,
    i32::MAX as i128,
    i32::MIN as i128,
    u32::MAX as i128,
    u32::MAX as i128 + 1,
    1 << 53,
    i64::MAX as i128,
    i64::MIN as i128,
    u64::MAX as i128,
    5120,
    5123,
    5125,
    5126,
    34963,
];

/// Floats that are boundaries for f32 fields (past f32::MAX, subnormal) and plain oddities.
const FLOATS: [f64; 10] = [
    0.5, -0.5, -0.0, 1e-30, 1e-45, 1e30, 3.4e38, 1e39, 1e300, -1e300,
];

/// An interesting number as a JSON value.
pub fn number(d: &mut Dice) -> Value {
    if d.chance(0.7) {
        match *d.pick(&INTS) {
            v if v < 0 => Value::from(v as i64),
            v => Value::from(v as u64),
        }
    } else {
        Number::from_f64(*d.pick(&FLOATS)).map_or(Value::Null, Value::Number)
    }
}

/// A random value of a random type (for type confusion).
fn any_value(d: &mut Dice, dict: &[&str]) -> Value {
    match d.below(7) {
        0 => Value::Null,
        1 => Value::Bool(d.chance(0.5)),
        2 => number(d),
        3 => Value::String(d.pick(dict).to_string()),
        4 => Value::Array(vec![]),
        5 => Value::Array((0..1 + d.below(4)).map(|_| number(d)).collect()),
        _ => Value::Object(Map::new()),
    }
}

/// Applies one structural mutation somewhere in `v`. `dict` holds strings worth trying (names
/// and keys of the format), used as replacement strings and as new keys.
pub fn mutate(v: &mut Value, d: &mut Dice, dict: &[&str]) {
    let mut node = v;
    loop {
        let n = match node {
            Value::Array(a) => a.len(),
            Value::Object(o) => o.len(),
            _ => 0,
        };
        if n == 0 || d.chance(0.12) {
            break;
        }
        let i = d.below(n);
        node = match node {
            Value::Array(a) => &mut a[i],
            Value::Object(o) => match o.values_mut().nth(i) {
                Some(child) => child,
                None => unreachable!("i < len"),
            },
            _ => unreachable!("n > 0 only for containers"),
        };
    }
    mutate_node(node, d, dict);
}

fn mutate_node(node: &mut Value, d: &mut Dice, dict: &[&str]) {
    match node {
        Value::Number(n) => {
            *node = match d.below(10) {
                0..=6 => number(d),
                7 | 8 => {
                    let x = n.as_f64().unwrap_or(0.0);
                    let y = *d.pick(&[x + 1.0, x - 1.0, x * 2.0, -x, x / 2.0, x * 1e6]);
                    if y.fract() == 0.0 && y.abs() < 1e18 {
                        Value::from(y as i64)
                    } else {
                        Number::from_f64(y).map_or(Value::Null, Value::Number)
                    }
                }
                _ => any_value(d, dict),
            }
        }
        Value::String(s) => match d.below(8) {
            0..=2 => *s = d.pick(dict).to_string(),
            3 => s.clear(),
            4 => {
                if s.pop().is_none() {
                    s.push('x');
                }
            }
            5 => s.push(*d.pick(&['0', '1', '.', '_', '"', '\\', ' ', 'é'])),
            // Long strings, but bounded: repeated mutation must not grow inputs without end.
            6 if s.len() <= 256 => *s = s.repeat(1 + d.below(64)),
            _ => *node = any_value(d, dict),
        },
        Value::Bool(b) => {
            if d.chance(0.7) {
                *b = !*b;
            } else {
                *node = any_value(d, dict);
            }
        }
        Value::Null => *node = any_value(d, dict),
        Value::Array(a) => {
            let n = a.len();
            match d.below(8) {
                0 | 1 if n > 0 => {
                    a.remove(d.below(n));
                }
                2 | 3 if n > 0 => {
                    let e = a[d.below(n)].clone();
                    a.insert(d.below(n + 1), e);
                }
                4 if n > 1 => {
                    let (i, j) = (d.below(n), d.below(n));
                    a.swap(i, j);
                }
                5 => a.truncate(d.below(n + 1)),
                6 => a.push(number(d)),
                _ => *node = any_value(d, dict),
            }
        }
        Value::Object(o) => {
            let keys: Vec<String> = o.keys().cloned().collect();
            let n = keys.len();
            match d.below(8) {
                0..=2 if n > 0 => {
                    o.remove(&keys[d.below(n)]);
                }
                3 if n > 1 => {
                    let a = &keys[d.below(n)];
                    let b = &keys[d.below(n)];
                    if let Some(v) = o.get(b).cloned() {
                        o.insert(a.clone(), v);
                    }
                }
                4 if n > 0 => {
                    let k = &keys[d.below(n)];
                    if let Some(v) = o.get(k).cloned() {
                        o.insert(format!("{k}{}", d.below(3)), v);
                    }
                }
                5 | 6 => {
                    let k = d.pick(dict).to_string();
                    let v = any_value(d, dict);
                    o.insert(k, v);
                }
                _ => *node = any_value(d, dict),
            }
        }
    }
}
