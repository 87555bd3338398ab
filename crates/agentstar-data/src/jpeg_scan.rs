//! A check of a sequential (baseline or extended) Huffman JPEG's entropy-coded data: every
//! block of every scan decodes with valid codes, each restart interval ends on the restart
//! marker it should, and each scan ends exactly where its data does.
//!
//! Decoders fill what they cannot decode with grey or repeated blocks and carry on (so do
//! browsers); a frame cut mid-scan with its end marker put back, or with a run of bytes
//! overwritten, then renders without complaint. JPEG has no checksum, so this walk (codes
//! and coefficient counts, no inverse DCT) is what can tell: a corruption desynchronises the
//! Huffman stream, which then runs out early, meets an invalid code or more than 64
//! coefficients, or leaves data after the last block. Progressive, lossless, arithmetic-coded
//! and DNL-sized images are not walked (`Ok(())`); the decoder's strict mode covers them.

/// What is wrong with the scan, in words for a person.
pub type ScanError = String;

#[derive(Clone, Default)]
struct Huffman {
    /// For each code length 1..=16: the largest code of that length (or -1), the first
    /// code and the index of its symbol.
    max_code: [i32; 17],
    min_code: [i32; 17],
    first_symbol: [usize; 17],
    symbols: Vec<u8>,
}

impl Huffman {
    fn new(counts: &[u8; 16], symbols: Vec<u8>) -> Result<Huffman, ScanError> {
        let mut h = Huffman {
            max_code: [-1; 17],
            symbols,
            ..Huffman::default()
        };
        let (mut code, mut k) = (0i32, 0usize);
        for len in 1..=16 {
            let n = counts[len - 1] as usize;
            h.first_symbol[len] = k;
            h.min_code[len] = code;
            code += n as i32;
            k += n;
            if n > 0 {
                h.max_code[len] = code - 1;
            }
            if code > (1 << len) {
                return Err("a Huffman table has more codes than its lengths allow".into());
            }
            code <<= 1;
        }
        if k != h.symbols.len() {
            return Err("a Huffman table's counts do not match its symbols".into());
        }
        Ok(h)
    }
}

struct Component {
    id: u8,
    h: usize,
    v: usize,
}

struct Bits<'a> {
    data: &'a [u8],
    pos: usize,
    byte: u8,
    left: u8,
}

impl Bits<'_> {
    fn bit(&mut self) -> Result<u32, ScanError> {
        if self.left == 0 {
            let b = *self
                .data
                .get(self.pos)
                .ok_or("the file ends inside the scan")?;
            if b == 0xFF {
                match self.data.get(self.pos + 1) {
                    Some(0x00) => self.pos += 2,
                    _ => return Err("the scan ends before its last block".into()),
                }
            } else {
                self.pos += 1;
            }
            self.byte = b;
            self.left = 8;
        }
        self.left -= 1;
        Ok(u32::from((self.byte >> self.left) & 1))
    }
    fn bits(&mut self, n: u8) -> Result<(), ScanError> {
        for _ in 0..n {
            self.bit()?;
        }
        Ok(())
    }
    fn decode(&mut self, t: &Huffman) -> Result<u8, ScanError> {
        let mut code = 0i32;
        for len in 1..=16 {
            code = (code << 1) | self.bit()? as i32;
            if code <= t.max_code[len] {
                let i = t.first_symbol[len] + (code - t.min_code[len]) as usize;
                return t
                    .symbols
                    .get(i)
                    .copied()
                    .ok_or_else(|| "a Huffman code has no symbol".to_string());
            }
        }
        Err("an invalid Huffman code in the scan".into())
    }
    /// Drops the rest of the current byte (restart intervals and scans end byte-aligned).
    fn align(&mut self) {
        self.left = 0;
    }
}

fn block(bits: &mut Bits, dc: &Huffman, ac: &Huffman) -> Result<(), ScanError> {
    let s = bits.decode(dc)?;
    if s > 11 {
        return Err("a DC coefficient of more than 11 bits".into());
    }
    bits.bits(s)?;
    let mut k = 1;
    while k < 64 {
        let rs = bits.decode(ac)?;
        let (r, s) = (rs >> 4, rs & 15);
        if s == 0 {
            if r == 15 {
                k += 16;
                continue;
            }
            break;
        }
        k += r as usize;
        if k > 63 || s > 10 {
            return Err("a block with more than 64 coefficients".into());
        }
        bits.bits(s)?;
        k += 1;
    }
    if k > 64 {
        return Err("a block with more than 64 coefficients".into());
    }
    Ok(())
}

fn u16_at(b: &[u8], i: usize) -> Result<usize, ScanError> {
    match (b.get(i), b.get(i + 1)) {
        (Some(&h), Some(&l)) => Ok(usize::from(u16::from_be_bytes([h, l]))),
        _ => Err("the file ends inside a header".into()),
    }
}

/// Walks a whole JPEG; `Err` says what is wrong with its entropy-coded data.
pub fn check(bytes: &[u8]) -> Result<(), ScanError> {
    if !bytes.starts_with(&[0xFF, 0xD8]) {
        return Err("no start-of-image marker".into());
    }
    let mut dc: [Option<Huffman>; 4] = Default::default();
    let mut ac: [Option<Huffman>; 4] = Default::default();
    let mut comps: Vec<Component> = Vec::new();
    let (mut width, mut height) = (0usize, 0usize);
    let mut restart = 0usize;
    let mut pos = 2;
    loop {
        // Fill bytes before a marker are allowed.
        while bytes.get(pos) == Some(&0xFF) && bytes.get(pos + 1) == Some(&0xFF) {
            pos += 1;
        }
        let (Some(&0xFF), Some(&m)) = (bytes.get(pos), bytes.get(pos + 1)) else {
            return Err(format!("no marker at byte {pos} (data between segments)"));
        };
        pos += 2;
        match m {
            0xD9 => return Ok(()),
            0xD0..=0xD7 | 0x01 => continue,
            _ => {}
        }
        let len = u16_at(bytes, pos)?;
        if len < 2 || pos + len > bytes.len() {
            return Err("a segment runs past the end of the file".into());
        }
        let seg = &bytes[pos + 2..pos + len];
        pos += len;
        match m {
            0xC0 | 0xC1 => {
                if seg.len() < 6 {
                    return Err("a short frame header".into());
                }
                height = u16_at(seg, 1)?;
                width = u16_at(seg, 3)?;
                let n = usize::from(seg[5]);
                comps.clear();
                for i in 0..n {
                    let c = seg
                        .get(6 + 3 * i..9 + 3 * i)
                        .ok_or("a short frame header")?;
                    let (h, v) = (usize::from(c[1] >> 4), usize::from(c[1] & 15));
                    if !(1..=4).contains(&h) || !(1..=4).contains(&v) {
                        return Err("a component's sampling factor is out of range".into());
                    }
                    comps.push(Component { id: c[0], h, v });
                }
                if height == 0 || width == 0 || comps.is_empty() {
                    // Height from a DNL marker, or nothing to walk: left to the decoder.
                    return Ok(());
                }
            }
            // Progressive, lossless, hierarchical or arithmetic-coded: not walked.
            0xC2 | 0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF => return Ok(()),
            0xC4 => {
                let mut i = 0;
                while i < seg.len() {
                    let tc_th = seg[i];
                    let counts: [u8; 16] = seg
                        .get(i + 1..i + 17)
                        .ok_or("a short Huffman table")?
                        .try_into()
                        .map_err(|_| "a short Huffman table")?;
                    let n: usize = counts.iter().map(|&c| usize::from(c)).sum();
                    let symbols = seg.get(i + 17..i + 17 + n).ok_or("a short Huffman table")?;
                    let table = Huffman::new(&counts, symbols.to_vec())?;
                    let slot = usize::from(tc_th & 15).min(3);
                    if tc_th >> 4 == 0 {
                        dc[slot] = Some(table);
                    } else {
                        ac[slot] = Some(table);
                    }
                    i += 17 + n;
                }
            }
            0xDD => restart = u16_at(seg, 0)?,
            0xDA => {
                if comps.is_empty() {
                    return Err("a scan before the frame header".into());
                }
                pos = scan(bytes, pos, seg, &comps, width, height, restart, &dc, &ac)?;
            }
            _ => {}
        }
    }
}

/// Walks one scan whose data starts at `start`; returns where its data ends.
#[allow(clippy::too_many_arguments)]
fn scan(
    bytes: &[u8],
    start: usize,
    header: &[u8],
    comps: &[Component],
    width: usize,
    height: usize,
    restart: usize,
    dc: &[Option<Huffman>; 4],
    ac: &[Option<Huffman>; 4],
) -> Result<usize, ScanError> {
    let n = usize::from(*header.first().ok_or("a short scan header")?);
    let mut members = Vec::with_capacity(n);
    for i in 0..n {
        let s = header
            .get(1 + 2 * i..3 + 2 * i)
            .ok_or("a short scan header")?;
        let ci = comps
            .iter()
            .position(|c| c.id == s[0])
            .ok_or("a scan names a component the frame does not have")?;
        let (td, ta) = (usize::from(s[1] >> 4).min(3), usize::from(s[1] & 15).min(3));
        let tables = dc[td].as_ref().zip(ac[ta].as_ref());
        members.push((
            ci,
            tables.ok_or("a scan uses a Huffman table that is not defined")?,
        ));
    }
    let hmax = comps.iter().map(|c| c.h).max().unwrap_or(1);
    let vmax = comps.iter().map(|c| c.v).max().unwrap_or(1);
    // Blocks per MCU for each member and the number of MCUs.
    let (mcus, per_mcu): (usize, Vec<usize>) = if members.len() == 1 {
        let c = &comps[members[0].0];
        let w = (width * c.h).div_ceil(hmax).div_ceil(8);
        let h = (height * c.v).div_ceil(vmax).div_ceil(8);
        (w * h, vec![1])
    } else {
        let w = width.div_ceil(8 * hmax);
        let h = height.div_ceil(8 * vmax);
        (
            w * h,
            members
                .iter()
                .map(|(ci, _)| comps[*ci].h * comps[*ci].v)
                .collect(),
        )
    };
    let mut bits = Bits {
        data: bytes,
        pos: start,
        byte: 0,
        left: 0,
    };
    let mut expected_rst = 0u8;
    for mcu in 0..mcus {
        if restart > 0 && mcu > 0 && mcu % restart == 0 {
            bits.align();
            match (bytes.get(bits.pos), bytes.get(bits.pos + 1)) {
                (Some(0xFF), Some(&m)) if m == 0xD0 + expected_rst => bits.pos += 2,
                _ => {
                    return Err(format!(
                        "restart interval {} does not end on its marker (MCU {mcu} of {mcus})",
                        mcu / restart
                    ))
                }
            }
            expected_rst = (expected_rst + 1) % 8;
        }
        for ((_, (dct, act)), &count) in members.iter().zip(&per_mcu) {
            for _ in 0..count {
                block(&mut bits, dct, act).map_err(|e| format!("{e} (MCU {mcu} of {mcus})"))?;
            }
        }
    }
    bits.align();
    // The scan's data must end here: a marker (or fill bytes before one) follows.
    match (bytes.get(bits.pos), bytes.get(bits.pos + 1)) {
        (Some(0xFF), Some(&m)) if m != 0x00 => Ok(bits.pos),
        (None, _) => Err("the file ends after the scan without an end-of-image marker".into()),
        _ => Err("data after the scan's last block (the scan is corrupt)".into()),
    }
}
