//! Mutated files against a reader: truncations, byte flips, forged sizes and counts, inserted
//! bytes and numbers. A family (a valid seed file and how to read one) runs in a child process
//! of the test binary under [`run_limited`](crate::run_limited) (2 GiB of address space) and a
//! deadline; its peak memory must stay under [`PEAK_MEMORY_LIMIT`](crate::PEAK_MEMORY_LIMIT).
//! A mutated file must be refused with an error that names it, or read: never a panic, never
//! more memory, never a hang.

use std::path::Path;
use std::time::{Duration, Instant};

/// Mutations per family.
pub const MUTATIONS: usize = 200;
/// How long a family's child may take.
pub const DEADLINE: Duration = Duration::from_secs(90);
/// The variable that makes a test binary a child reading one family.
const CHILD: &str = "RMVP_MUTATION_FAMILY";

/// A reader family: its seed file (a valid one) and how to read a file of it.
pub struct Family {
    /// Its name (`png`, `colmap-bin`); the test that runs it is `<name>_family` with `-` as `_`.
    pub name: &'static str,
    /// The name each mutated file is written under.
    pub file_name: &'static str,
    /// The valid file the mutations start from (given a scratch folder).
    pub seed: fn(&Path) -> Vec<u8>,
    /// Read a file of the family: `Err` is its error message.
    pub read: fn(&Path) -> Result<(), String>,
    /// Make a mutated file consistent again where its format checks itself (a PNG's header
    /// checksum), so that a forged size reaches the reader as a forger would send it.
    pub fixup: fn(&mut [u8]),
}

/// A family's `fixup` for formats without checksums.
pub fn no_fixup(_: &mut [u8]) {}

/// `Ok(())` or the error's message: what a family's `read` returns.
pub fn outcome<T, E: std::fmt::Display>(result: Result<T, E>) -> Result<(), String> {
    result.map(drop).map_err(|e| e.to_string())
}

/// SplitMix64: the mutations' own deterministic numbers.
struct Rng(u64);

impl Rng {
    fn next_u32(&mut self) -> u32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 32) as u32
    }
}

/// Numbers a forged size or count is made of.
const FORGED: [u64; 8] = [0, 1 << 20, 1 << 24, 1 << 31, u32::MAX as u64, 100_000, 200_000, u64::MAX];

/// Where a forged field of `width` bytes goes: half the time a 4-byte-aligned offset in the first
/// 64 bytes, else anywhere in the first 512.
fn forged_offset(rng: &mut Rng, len: usize, width: usize) -> usize {
    let room = len.saturating_sub(width).max(1);
    if rng.next_u32().is_multiple_of(2) {
        (4 * (rng.next_u32() as usize % 16)).min(room - 1)
    } else {
        rng.next_u32() as usize % room.min(512)
    }
}

/// Forged fields swept before the random mutations: every 4-byte-aligned offset of the first 64
/// bytes, with 2^20 and 2^24, big- and little-endian (the size fields of binary headers).
const SWEPT: usize = 16 * 4;

/// The `i`-th swept forgery of `seed`, and what it was.
fn sweep(seed: &[u8], i: usize) -> (Vec<u8>, String) {
    let mut bytes = seed.to_vec();
    let at = 4 * (i / 4);
    let value: u32 = if i.is_multiple_of(2) { 1 << 20 } else { 1 << 24 };
    let big_endian = (i / 2).is_multiple_of(2);
    let word = if big_endian { value.to_be_bytes() } else { value.to_le_bytes() };
    if at + 4 <= bytes.len() {
        bytes[at..at + 4].copy_from_slice(&word);
    }
    let order = if big_endian { "big" } else { "little" };
    (bytes, format!("forged {order}-endian {value} at byte {at}"))
}

/// One mutation of `seed`, and what it was.
fn mutate(seed: &[u8], rng: &mut Rng) -> (Vec<u8>, String) {
    let mut bytes = seed.to_vec();
    let at = |rng: &mut Rng, len: usize| (rng.next_u32() as usize) % len.max(1);
    match rng.next_u32() % 6 {
        0 => {
            let keep = at(rng, bytes.len());
            bytes.truncate(keep);
            (bytes, format!("truncated to {keep} bytes"))
        }
        1 => {
            let flips = 1 + rng.next_u32() % 8;
            for _ in 0..flips {
                let i = at(rng, bytes.len());
                bytes[i] ^= 1 << (rng.next_u32() % 8);
            }
            (bytes, format!("{flips} bits flipped"))
        }
        2 => {
            // A forged 32-bit field: sizes and counts live near the start of every format, most
            // at aligned offsets of its first 64 bytes.
            let i = forged_offset(rng, bytes.len(), 4);
            let value = FORGED[(rng.next_u32() as usize) % FORGED.len()] as u32;
            let big_endian = rng.next_u32().is_multiple_of(2);
            let word = if big_endian { value.to_be_bytes() } else { value.to_le_bytes() };
            bytes[i..i + 4].copy_from_slice(&word);
            (bytes, format!("forged 32-bit {value} at byte {i}"))
        }
        3 => {
            // A number in the text replaced by a forged one, NaN or a negative.
            let text_numbers: Vec<usize> =
                (1..bytes.len()).filter(|&i| bytes[i].is_ascii_digit() && !bytes[i - 1].is_ascii_digit()).collect();
            if text_numbers.is_empty() {
                bytes.clear();
                return (bytes, "emptied".into());
            }
            let i = text_numbers[(rng.next_u32() as usize) % text_numbers.len()];
            let end = (i..bytes.len()).find(|&k| !bytes[k].is_ascii_digit()).unwrap_or(bytes.len());
            let choices = ["4294967296", "99999999999999999999", "nan", "-1", "1e308", "0"];
            let by = choices[(rng.next_u32() as usize) % choices.len()];
            bytes.splice(i..end, by.bytes());
            (bytes, format!("number at byte {i} replaced by {by}"))
        }
        4 => {
            let i = at(rng, bytes.len());
            let n = 1 + rng.next_u32() % 64;
            let noise: Vec<u8> = (0..n).map(|_| rng.next_u32() as u8).collect();
            bytes.splice(i..i, noise);
            (bytes, format!("{n} bytes inserted at {i}"))
        }
        _ => {
            // A forged 64-bit field.
            let i = forged_offset(rng, bytes.len(), 8);
            let value = FORGED[(rng.next_u32() as usize) % FORGED.len()];
            bytes[i..i + 8].copy_from_slice(&value.to_le_bytes());
            (bytes, format!("forged 64-bit {value} at byte {i}"))
        }
    }
}

/// In the child: read every mutation of the family, print one line before each (the last line
/// names the culprit of an abort or a hang) and a summary.
fn child(family: &Family) {
    let dir = tempfile_dir();
    let seed = (family.seed)(&dir);
    let seed_path = dir.join(family.file_name);
    std::fs::write(&seed_path, &seed).unwrap();
    (family.read)(&seed_path).unwrap_or_else(|e| panic!("the seed file of {} does not read: {e}", family.name));
    let mut rng = Rng(family.name.bytes().fold(39, |h, b| h.wrapping_mul(31).wrapping_add(b as u64)));
    let (mut refused, mut read) = (0, 0);
    let mut panics = Vec::new();
    std::panic::set_hook(Box::new(|_| {}));
    for i in 0..MUTATIONS {
        let (mut bytes, what) = if i < SWEPT { sweep(&seed, i) } else { mutate(&seed, &mut rng) };
        (family.fixup)(&mut bytes);
        let case = dir.join(format!("case{i}"));
        std::fs::create_dir_all(&case).unwrap();
        let path = case.join(family.file_name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &bytes).unwrap();
        println!("mutation {i}: {what}");
        match std::panic::catch_unwind(|| (family.read)(&path)) {
            Ok(Ok(())) => read += 1,
            Ok(Err(message)) => {
                assert!(
                    message.contains(&path.display().to_string()),
                    "mutation {i} ({what}): {message:?} does not name the file"
                );
                refused += 1;
            }
            Err(_) => panics.push(format!("mutation {i} ({what})")),
        }
        std::fs::remove_dir_all(&case).unwrap();
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!("summary {}: {MUTATIONS} mutations, {refused} refused, {read} read, {} panics", family.name, panics.len());
    assert!(panics.is_empty(), "panics: {panics:?}");
}

/// A fresh scratch folder under the system's temporary folder.
fn tempfile_dir() -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("rmvp-mutations-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Run family `name` of `families`: in the parent test, start this test binary as a child that
/// reads its mutations under the limits and check what it did; in that child, read them.
pub fn run_family(families: &[Family], name: &str) {
    let family = families.iter().find(|f| f.name == name).unwrap_or_else(|| panic!("no family {name}"));
    if let Ok(wanted) = std::env::var(CHILD) {
        if wanted == name {
            child(family);
        }
        return;
    }
    let test = format!("{}_family", name.replace('-', "_"));
    let started = Instant::now();
    let run = crate::run_test_in_child(&test, (CHILD, name), DEADLINE);
    let lines: Vec<&str> = run.stdout.lines().collect();
    let last = lines.iter().rev().find(|l| l.starts_with("mutation ")).copied().unwrap_or_default();
    let summary = lines.iter().find(|l| l.starts_with("summary ")).copied();
    let stderr = &run.stderr;
    match run.status {
        None => panic!("{name}: hung past {DEADLINE:?} at {last}"),
        Some(s) if !s.success() => panic!("{name}: the reader failed ({s}) at {last}\n{stderr}"),
        Some(_) => {}
    }
    let summary = summary.unwrap_or_else(|| panic!("{name}: no summary\n{}", lines.join("\n")));
    let peak_mib = run.peak_bytes as f64 / (1 << 20) as f64;
    eprintln!("{summary}, peak {peak_mib:.0} MiB, in {:.1} s", started.elapsed().as_secs_f64());
    assert!(summary.contains(&format!("{MUTATIONS} mutations")) && summary.ends_with(", 0 panics"), "{summary}");
    assert!(
        run.peak_bytes < crate::PEAK_MEMORY_LIMIT,
        "{name}: a mutation took {peak_mib:.0} MiB (the last read: {last})"
    );
}
