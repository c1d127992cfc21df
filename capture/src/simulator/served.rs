//! A real FLIR camera's GenICam description served by the simulated camera, every node, type
//! and formula as the camera has it, over the simulator's registers.
//!
//! aravis's fake camera backs 64 KiB of registers; a Blackfly S description addresses its
//! registers far above that (`0x000C1004`, `0x20000344`, ...). Each register is moved into the
//! window: its `<Address>` rewritten, and for registers whose address a formula computes from a
//! selector (`<pAddress>`), the formula's base constants moved, each base keeping a window of
//! `SELECTOR_WINDOW` bytes for its selector's entries. The registers the fake camera streams
//! from (`Width`, `Height`, `PixelFormat` and `AcquisitionStart`'s values) land on the fake
//! camera's own addresses, in its byte order. A GigE Vision description's bootstrap registers
//! (below 0x1000) stay where the fake camera implements them. Nothing else changes: the served
//! file has the camera's nodes, with the simulated rig's few nodes added.
//!
//! What the camera's firmware would hold in those registers, the simulator writes
//! ([`ServedDescription::initial`]): every `_Imp`, `_Avl` and `_Inq` flag set except the pixel
//! formats it cannot stream, limits and values of a BFS-U3-51S5PC-C, and the fixed-point scales
//! the description's converters read (`_Posn`, frame-rate numerators).

use crate::{Error, Result};
use roxmltree::{Document, Node};
use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;

/// Bytes kept for each selector-indexed block of registers (16 entries of FLIR's 0x20).
const SELECTOR_WINDOW: u32 = 0x200;
/// Where moved registers start: above the bootstrap block, the fake camera's own registers and
/// the simulated rig's.
const FIRST_MOVED: u32 = 0x2000;
/// Where every register too long to move (lookup tables, user memory) is pointed: nothing the
/// simulator serves reads them.
const SCRATCH: u32 = 0xF000;
/// Longest register moved into its own place.
const LONGEST_MOVED: u32 = 512;
/// A description file larger than this is refused (FLIR's are about 1 MB).
const MAX_DESCRIPTION_BYTES: u64 = 16 << 20;

/// The registers the fake camera streams from: node name, its address there.
const STREAMING_REGISTERS: [(&str, u32); 4] =
    [("Width_Val", 0x100), ("Height_Val", 0x104), ("AcquisitionStart_Val", 0x124), ("PixelFormat_Val", 0x128)];

/// The GenICam nodes that are registers.
const REGISTER_NODES: [&str; 6] = ["IntReg", "MaskedIntReg", "FloatReg", "StringReg", "Register", "StructReg"];

/// A register of the served description, where it now lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Register {
    /// Byte address in the fake camera's memory.
    pub address: u32,
    /// Bytes.
    pub length: u32,
    /// Byte order.
    pub little_endian: bool,
}

impl Register {
    /// The bytes of `value` in this register's length and order (integers of 4 or 8 bytes).
    pub fn bytes(&self, value: u64) -> Vec<u8> {
        let bytes = value.to_le_bytes();
        let mut out = bytes[..self.length.min(8) as usize].to_vec();
        if !self.little_endian {
            out.reverse();
        }
        out
    }
}

/// A description ready to serve.
pub struct ServedDescription {
    /// The description with its registers moved and the rig's nodes added.
    pub xml: String,
    /// Every register node by name (those addressed through a selector: at its first entry).
    pub registers: HashMap<String, Register>,
    /// The pixel formats offered: the description's that the simulator streams, with their codes.
    pub pixel_formats: Vec<(String, u32)>,
    /// Register contents to write before serving: address and bytes.
    pub initial: Vec<(u32, Vec<u8>)>,
    /// The model the description names (`ModelName` of its root).
    pub model: String,
    /// Every one-bit flag (`MaskedIntReg` with `<Bit>`, `StructEntry`): its register (one per
    /// entry of its selector) and value bit (0 = least significant).
    flags: HashMap<String, (Vec<Register>, u32)>,
}

/// A register node as the description has it.
struct Found<'a> {
    node: Node<'a, 'a>,
    name: &'a str,
    address: u64,
    length: u32,
    little_endian: bool,
    selector_base: Option<&'a str>,
}

impl ServedDescription {
    /// Read the description at `path` and move its registers into the fake camera's window.
    /// `streamable` names the pixel formats the simulator can stream; `rig` is XML of the
    /// simulated rig's own nodes (a `Category` named `Simulation` and what it lists).
    pub fn load(path: &Path, streamable: &[&str], rig: &str) -> Result<Self> {
        let bytes = rmvp_dataset::io::input::read_bytes_limited(path, MAX_DESCRIPTION_BYTES)?;
        let text = String::from_utf8_lossy(&bytes);
        // Some cameras' files start with a line of their own before the XML declaration.
        let start = text
            .find("<?xml")
            .or_else(|| text.find("<RegisterDescription"))
            .ok_or_else(|| Error::in_file(path, "holds no GenICam description (no <?xml or <RegisterDescription>)"))?;
        let text = &text[start..];
        let document = Document::parse(text).map_err(|e| Error::in_file(path, format!("not XML: {e}")))?;
        Self::from_document(&document, text, streamable, rig).map_err(|why| Error::in_file(path, why))
    }

    fn from_document(
        document: &Document,
        text: &str,
        streamable: &[&str],
        rig: &str,
    ) -> std::result::Result<Self, String> {
        let root = document.root_element();
        let model = root.attribute("ModelName").unwrap_or("camera").to_string();
        let gige = document.descendants().any(|n| n.attribute("Name") == Some("GevSCPSPacketSize"));
        let by_name: HashMap<&str, Node> = document
            .descendants()
            .filter(|n| n.is_element() && n.tag_name().name() != "EnumEntry")
            .filter_map(|n| n.attribute("Name").map(|a| (a, n)))
            .collect();
        let found: Vec<Found> = document
            .descendants()
            .filter(|n| n.is_element() && REGISTER_NODES.contains(&n.tag_name().name()))
            .filter(|n| child_text(*n, "pPort").is_none_or(|p| p == "Device"))
            .filter_map(|node| {
                let name = node.attribute("Name")?;
                // A register addressed through a selector may give no offset of its own.
                let address = match child_text(node, "Address") {
                    Some(text) => parse_integer(text)?,
                    None if child(node, "pAddress").is_some() => 0,
                    None => return None,
                };
                let length = child_text(node, "Length").and_then(parse_integer).unwrap_or(4) as u32;
                let little_endian = child_text(node, "Endianess").is_none_or(|e| e == "LittleEndian");
                Some(Found { node, name, address, length, little_endian, selector_base: child_text(node, "pAddress") })
            })
            .collect();

        let mut edits: Vec<(Range<usize>, String)> = Vec::new();
        let mut next = FIRST_MOVED;
        let mut allocate = |bytes: u32| -> std::result::Result<u32, String> {
            let at = next;
            next += bytes.div_ceil(4) * 4;
            if next > SCRATCH {
                return Err(format!(
                    "its registers need more than the {} bytes the simulator has",
                    SCRATCH - FIRST_MOVED
                ));
            }
            Ok(at)
        };
        // Selector-indexed blocks: the constants of each address formula moved.
        let mut moved_bases: HashMap<&str, u32> = HashMap::new();
        let mut strides: HashMap<&str, u32> = HashMap::new();
        for base in found.iter().filter_map(|f| f.selector_base) {
            if moved_bases.contains_key(base) {
                continue;
            }
            let Some(formula) = by_name.get(base).and_then(|n| child(*n, "Formula")) else { continue };
            let Some(formula_text) = formula.first_child() else { continue };
            let formula = formula_text.text().unwrap_or("");
            let (rewritten, first) = move_constants(formula, &mut allocate)?;
            edits.push((formula_text.range(), escape(&rewritten)));
            moved_bases.insert(base, first.unwrap_or(0));
            strides.insert(base, stride(formula));
        }
        // Every other register: its own place, or the fake camera's for the streaming ones.
        let mut registers = HashMap::new();
        let mut moved: HashMap<u64, u32> = HashMap::new();
        let mut longest: HashMap<u64, u32> = HashMap::new();
        for f in found.iter().filter(|f| f.selector_base.is_none()) {
            let entry = longest.entry(f.address).or_insert(0);
            *entry = (*entry).max(f.length);
        }
        for f in &found {
            let (address, little_endian) = if let Some(base) = f.selector_base {
                (moved_bases.get(base).copied().unwrap_or(0) + f.address as u32, f.little_endian)
            } else if let Some(&(_, at)) = STREAMING_REGISTERS.iter().find(|(n, _)| *n == f.name) {
                if let Some(endianness) = child(f.node, "Endianess").and_then(|e| e.first_child()) {
                    edits.push((endianness.range(), "BigEndian".into()));
                }
                (at, false)
            } else if gige && f.address < 0x1000 {
                (f.address as u32, f.little_endian)
            } else if longest[&f.address] > LONGEST_MOVED {
                (SCRATCH, f.little_endian)
            } else {
                let at = match moved.get(&f.address) {
                    Some(&at) => at,
                    None => {
                        let at = allocate(longest[&f.address])?;
                        moved.insert(f.address, at);
                        at
                    }
                };
                (at, f.little_endian)
            };
            if f.selector_base.is_none() {
                let text_node = child(f.node, "Address").and_then(|a| a.first_child()).expect("has an address");
                edits.push((text_node.range(), format!("0x{address:08X}")));
            }
            registers.insert(f.name.to_string(), Register { address, length: f.length, little_endian });
        }

        // The rig's nodes beside the camera's, listed under the root category.
        let root_category = by_name.get("Root").ok_or("has no Root category")?;
        let close = root_category.range().end - "</Category>".len();
        edits.push((close..close, "<pFeature>Simulation</pFeature>".into()));
        let end = root.range().end - format!("</{}>", root.tag_name().name()).len();
        edits.push((end..end, rig.to_string()));

        edits.sort_by_key(|(range, _)| std::cmp::Reverse(range.start));
        let mut xml = text.to_string();
        for (range, replacement) in edits {
            xml.replace_range(range, &replacement);
        }

        let pixel_formats: Vec<(String, u32)> = by_name
            .get("PixelFormat")
            .map(|n| {
                n.children()
                    .filter(|e| e.tag_name().name() == "EnumEntry")
                    .filter_map(|e| {
                        Some((e.attribute("Name")?.to_string(), parse_integer(child_text(e, "Value")?)? as u32))
                    })
                    .filter(|(name, _)| streamable.contains(&name.as_str()))
                    .collect()
            })
            .unwrap_or_default();
        if pixel_formats.is_empty() {
            return Err(format!("offers none of the pixel formats the simulator streams ({})", streamable.join(", ")));
        }
        let mut flags = HashMap::new();
        for f in &found {
            let register = registers[f.name];
            // A flag addressed through a selector is set for every entry of its window.
            let copies = f.selector_base.and_then(|b| strides.get(b)).map_or(1, |&stride| SELECTOR_WINDOW / stride);
            let stride = f.selector_base.and_then(|b| strides.get(b)).copied().unwrap_or(0);
            let bits = std::iter::once((f.name, f.node)).chain(
                f.node
                    .children()
                    .filter(|c| c.tag_name().name() == "StructEntry")
                    .filter_map(|e| Some((e.attribute("Name")?, e))),
            );
            for (name, node) in bits {
                if let Some(bit) = child_text(node, "Bit").and_then(parse_integer) {
                    // GenICam numbers a big-endian register's bits from its most significant one.
                    let bit = bit as u32;
                    let bit = if register.little_endian { bit } else { 8 * register.length - 1 - bit };
                    let at = (0..copies).map(|k| Register { address: register.address + k * stride, ..register });
                    flags.insert(name.to_string(), (at.collect::<Vec<_>>(), bit));
                }
            }
        }
        let initial = initial_flags(&found, &registers, &by_name, &pixel_formats, &flags);
        Ok(Self { xml, registers, pixel_formats, initial, model, flags })
    }

    /// A register by node name, if the description has it.
    pub fn register(&self, name: &str) -> Option<Register> {
        self.registers.get(name).copied()
    }

    /// A one-bit flag's register (at its selector's first entry) and its value bit (0 = least
    /// significant).
    pub fn flag(&self, name: &str) -> Option<(Register, u32)> {
        self.flags.get(name).map(|(registers, bit)| (registers[0], *bit))
    }
}

/// Every `_Imp`, `_Avl` and `_Inq` flag set (bit by bit: a FLIR register holds a feature's
/// implemented, available and locked bits side by side), but the implemented flags of the pixel
/// formats not offered.
fn initial_flags(
    found: &[Found],
    registers: &HashMap<String, Register>,
    by_name: &HashMap<&str, Node>,
    offered: &[(String, u32)],
    flags: &HashMap<String, (Vec<Register>, u32)>,
) -> Vec<(u32, Vec<u8>)> {
    let is_flag = |name: &str| ["_Imp", "_Avl", "_Inq"].iter().any(|s| name.ends_with(s));
    let not_offered: Vec<&str> = by_name
        .get("PixelFormat")
        .map(|n| {
            n.children()
                .filter(|e| e.tag_name().name() == "EnumEntry")
                .filter(|e| !offered.iter().any(|(name, _)| Some(name.as_str()) == e.attribute("Name")))
                .filter_map(|e| child_text(e, "pIsImplemented"))
                .collect()
        })
        .unwrap_or_default();
    let mut words: HashMap<u32, (Register, u64)> = HashMap::new();
    for (name, (at, bit)) in flags {
        if is_flag(name) && !not_offered.contains(&name.as_str()) {
            for &register in at.iter().filter(|r| r.length <= 8) {
                words.entry(register.address).or_insert((register, 0)).1 |= 1 << bit;
            }
        }
    }
    // Flags held in a whole register of their own.
    for f in found.iter().filter(|f| is_flag(f.name) && !flags.contains_key(f.name) && f.length <= 8) {
        let register = registers[f.name];
        words.entry(register.address).or_insert((register, 0)).1 |= 1;
    }
    words.into_values().map(|(register, word)| (register.address, register.bytes(word))).collect()
}

/// A formula with its address constants (0x1000 and up: strides and small offsets stay)
/// moved to windows of their own; and the first one's new address.
fn move_constants(
    formula: &str,
    allocate: &mut impl FnMut(u32) -> std::result::Result<u32, String>,
) -> std::result::Result<(String, Option<u32>), String> {
    let mut out = String::new();
    let mut first = None;
    let mut rest = formula;
    while let Some(at) = rest.find("0x").or_else(|| rest.find("0X")) {
        out.push_str(&rest[..at]);
        let digits: String = rest[at + 2..].chars().take_while(char::is_ascii_hexdigit).collect();
        let value = u64::from_str_radix(&digits, 16).unwrap_or(0);
        rest = &rest[at + 2 + digits.len()..];
        if value >= 0x1000 {
            let moved = allocate(SELECTOR_WINDOW)?;
            first.get_or_insert(moved);
            out.push_str(&format!("0x{moved:08X}"));
        } else {
            out.push_str(&format!("0x{digits}"));
        }
    }
    out.push_str(rest);
    Ok((out, first))
}

/// The step between a selector's entries in an address formula (`BASE + 0x20 * (INDEX)`): its
/// first constant below 0x1000; FLIR's 0x20 when it has none.
fn stride(formula: &str) -> u32 {
    formula
        .match_indices("0x")
        .filter_map(|(at, _)| {
            let digits: String = formula[at + 2..].chars().take_while(char::is_ascii_hexdigit).collect();
            u32::from_str_radix(&digits, 16).ok()
        })
        .find(|&v| v > 0 && v < 0x1000)
        .unwrap_or(0x20)
}

fn child<'a>(node: Node<'a, 'a>, tag: &str) -> Option<Node<'a, 'a>> {
    node.children().find(|c| c.is_element() && c.tag_name().name() == tag)
}

fn child_text<'a>(node: Node<'a, 'a>, tag: &str) -> Option<&'a str> {
    child(node, tag).and_then(|c| c.text()).map(str::trim)
}

/// A GenICam integer: decimal or `0x` hexadecimal.
fn parse_integer(text: &str) -> Option<u64> {
    let text = text.trim();
    match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(hex, 16).ok(),
        None => text.parse().ok(),
    }
}

/// Text as XML character data.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}
