//! Byte- and text-level mutations, driven by the project's one random generator
//! (`prt_bake::sampling::Rng`), so a run is reproducible from its seed.

use prt_bake::sampling::Rng;

/// The random choices of a fuzz run.
pub struct Dice(Rng);

impl Dice {
    /// The stream of target `stream` for run seed `seed`.
    pub fn new(seed: u64, stream: u64) -> Dice {
        Dice(Rng::for_sample(seed, stream, 0))
    }

    pub fn u32(&mut self) -> u32 {
        self.0.next_u32()
    }

    pub fn u64(&mut self) -> u64 {
        ((self.0.next_u32() as u64) << 32) | self.0.next_u32() as u64
    }

    /// Uniform in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.u64() % n as u64) as usize
        }
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f32) -> bool {
        self.0.next_f32() < p
    }

    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }

    /// A length in `1..=max`, small lengths much more likely than large ones.
    pub fn chunk_len(&mut self, max: usize) -> usize {
        let cap = *self.pick(&[1usize, 2, 4, 8, 16, 64, 256, 4096, usize::MAX]);
        1 + self.below(cap.min(max.max(1)))
    }
}

/// Bytes that often sit on a boundary.
const BYTES: [u8; 10] = [0, 1, 0x7F, 0x80, 0xFF, 0x20, b'"', b'{', b'[', b'\\'];

/// 32-bit values on boundaries, including f32 bit patterns (inf, NaN, +-1, huge).
pub const U32S: [u32; 22] = [
    0,
    1,
    2,
    3,
    7,
    8,
    16,
    255,
    256,
    0x7FFF,
    0xFFFF,
    0x1_0000,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFE,
    0xFFFF_FFFF,
    0x7F80_0000, // f32 +inf
    0xFF80_0000, // f32 -inf
    0x7FC0_0000, // f32 NaN
    0x3F80_0000, // f32 1.0
    0xBF80_0000, // f32 -1.0
    0x7F7F_FFFF, // f32 MAX
];

/// 64-bit values on boundaries: huge lengths, sizes just past the limits.
pub const U64S: [u64; 14] = [
    0,
    1,
    8,
    16,
    0x7FFF_FFFF,
    0xFFFF_FFFF,
    1 << 32,
    1 << 40,
    1 << 53,
    100_000_000,
    100_000_001,
    0x7FFF_FFFF_FFFF_FFFF,
    0x8000_0000_0000_0000,
    u64::MAX,
];

/// Number spellings that probe parsers: boundaries of u32/i64/u64/f32/f64, non-finite values
/// (in TOML's spelling and others), malformed numbers.
pub const NUMBER_TOKENS: [&str; 40] = [
    "0",
    "-0",
    "1",
    "-1",
    "2",
    "3",
    "16",
    "255",
    "65536",
    "2147483647",
    "2147483648",
    "4294967295",
    "4294967296",
    "-2147483649",
    "9007199254740993",
    "9223372036854775807",
    "9223372036854775808",
    "-9223372036854775808",
    "18446744073709551615",
    "18446744073709551616",
    "0.5",
    "1e-45",
    "1e-320",
    "3.4e38",
    "3.5e38",
    "1e39",
    "-1e39",
    "1e308",
    "1e309",
    "-1e309",
    "nan",
    "inf",
    "-inf",
    "+nan",
    "NaN",
    "Infinity",
    "1e99999",
    "0x10",
    "1_000",
    "1.",
];

/// Applies 1 to 4 random byte-level mutations to `data`; `other` (another corpus entry) is
/// the source of splices; the result is cut to `max_len`.
pub fn havoc(data: &mut Vec<u8>, other: &[u8], d: &mut Dice, max_len: usize) {
    let n = 1 + d.below(4);
    for _ in 0..n {
        byte_op(data, other, d);
    }
    data.truncate(max_len);
}

fn write_at(data: &mut [u8], at: usize, bytes: &[u8]) {
    let end = (at + bytes.len()).min(data.len());
    if at < end {
        data[at..end].copy_from_slice(&bytes[..end - at]);
    }
}

/// One byte-level mutation.
pub fn byte_op(data: &mut Vec<u8>, other: &[u8], d: &mut Dice) {
    let len = data.len();
    match d.below(15) {
        0 if len > 0 => {
            let i = d.below(len);
            data[i] ^= 1 << d.below(8);
        }
        1 if len > 0 => {
            let i = d.below(len);
            data[i] = *d.pick(&BYTES);
        }
        2 if len > 0 => {
            let i = d.below(len);
            data[i] = d.u32() as u8;
        }
        3 if len > 0 => {
            let v = *d.pick(&U32S) as u16;
            let b = if d.chance(0.5) {
                v.to_le_bytes()
            } else {
                v.to_be_bytes()
            };
            write_at(data, d.below(len), &b);
        }
        4 if len > 0 => {
            let v = *d.pick(&U32S);
            write_at(data, d.below(len), &v.to_le_bytes());
        }
        5 if len > 0 => {
            let v = *d.pick(&U64S);
            // Length fields sit at the start of most containers: aim there half the time.
            let at = if d.chance(0.5) {
                d.below(len.min(24)) & !3
            } else {
                d.below(len)
            };
            write_at(data, at, &v.to_le_bytes());
        }
        6 if len > 0 => {
            let i = d.below(len);
            let delta = 1 + d.below(16) as u8;
            data[i] = if d.chance(0.5) {
                data[i].wrapping_add(delta)
            } else {
                data[i].wrapping_sub(delta)
            };
        }
        7 if len >= 4 => {
            let i = d.below(len - 3);
            let v = u32::from_le_bytes([data[i], data[i + 1], data[i + 2], data[i + 3]]);
            let delta = 1 + d.below(64) as u32;
            let v = if d.chance(0.5) {
                v.wrapping_add(delta)
            } else {
                v.wrapping_sub(delta)
            };
            data[i..i + 4].copy_from_slice(&v.to_le_bytes());
        }
        8 if len > 0 => data.truncate(d.below(len)),
        9 if len > 0 => {
            let at = d.below(len);
            let n = d.chunk_len(len - at);
            data.drain(at..(at + n).min(len));
        }
        10 if len > 0 => {
            let from = d.below(len);
            let n = d.chunk_len(len - from).min(len - from);
            let chunk = data[from..from + n].to_vec();
            let at = d.below(len + 1);
            data.splice(at..at, chunk);
        }
        11 => {
            let at = d.below(len + 1);
            let n = d.chunk_len(64);
            let fill: Vec<u8> = if d.chance(0.5) {
                vec![*d.pick(&BYTES); n]
            } else {
                (0..n).map(|_| d.u32() as u8).collect()
            };
            data.splice(at..at, fill);
        }
        12 if !other.is_empty() => {
            let from = d.below(other.len());
            let n = d.chunk_len(other.len() - from).min(other.len() - from);
            let chunk = &other[from..from + n];
            let at = d.below(len + 1);
            if d.chance(0.5) {
                data.splice(at..at, chunk.iter().copied());
            } else {
                let end = (at + n).min(len);
                data.splice(at..end, chunk.iter().copied());
            }
        }
        13 => replace_number(data, d),
        _ => {
            let at = d.below(len + 1);
            let tok = d.pick(&NUMBER_TOKENS).as_bytes();
            data.splice(at..at, tok.iter().copied());
        }
    }
}

/// Replaces one decimal number of a text (JSON, TOML) with a number token that probes parsers.
pub fn replace_number(data: &mut Vec<u8>, d: &mut Dice) {
    let spans = number_spans(data);
    if spans.is_empty() {
        return;
    }
    let (a, b) = *d.pick(&spans);
    let tok = d.pick(&NUMBER_TOKENS).as_bytes();
    data.splice(a..b, tok.iter().copied());
}

/// Byte ranges of the decimal numbers in a text.
fn number_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < data.len() {
        let c = data[i];
        let starts =
            c.is_ascii_digit() || (c == b'-' && data.get(i + 1).is_some_and(u8::is_ascii_digit));
        let after_word = i > 0 && (data[i - 1].is_ascii_alphanumeric() || data[i - 1] == b'_');
        if starts && !after_word {
            let a = i;
            i += 1;
            while i < data.len()
                && (data[i].is_ascii_digit() || matches!(data[i], b'.' | b'e' | b'E' | b'+' | b'-'))
            {
                i += 1;
            }
            out.push((a, i));
        } else {
            i += 1;
        }
    }
    out
}

/// Line-level mutations of a text: delete, duplicate, swap lines, or insert a line of `other`.
pub fn line_op(data: &mut Vec<u8>, other: &[u8], d: &mut Dice) {
    let mut lines: Vec<Vec<u8>> = data.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
    let n = lines.len();
    match d.below(4) {
        0 if n > 1 => {
            lines.remove(d.below(n));
        }
        1 => {
            let l = lines[d.below(n)].clone();
            lines.insert(d.below(n + 1), l);
        }
        2 if n > 1 => {
            let (a, b) = (d.below(n), d.below(n));
            lines.swap(a, b);
        }
        _ => {
            let theirs: Vec<&[u8]> = other.split(|&b| b == b'\n').collect();
            let l = theirs[d.below(theirs.len())].to_vec();
            lines.insert(d.below(n + 1), l);
        }
    }
    *data = lines.join(&b'\n');
}
