//! `lucent asm` and `lucent disasm`.

use anyhow::{bail, Context, Result};
use rend3r_isa::{
    assemble_words, disassemble, from_bin, from_mem, looks_legacy, to_bin, to_mem, AsmOptions, CameraTable, DisasmOptions, SetTable,
};
use std::path::{Path, PathBuf};

/// Output format of `asm`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum WordFormat {
    /// 8 lowercase hex digits per line, as REND3R's `.mem`.
    Mem,
    /// Raw u32 words in network byte order.
    Bin,
}

pub fn table(old: bool) -> CameraTable {
    if old {
        CameraTable::Old
    } else {
        CameraTable::Final
    }
}

pub fn asm(src: &Path, out: Option<PathBuf>, format: Option<WordFormat>, camera_table: CameraTable) -> Result<()> {
    let text = std::fs::read_to_string(src).with_context(|| format!("cannot read {}", src.display()))?;
    let words = assemble_words(&text, AsmOptions { camera_table }).map_err(|e| anyhow::anyhow!("{}:{e}", src.display()))?;
    let out = out.unwrap_or_else(|| src.with_extension(if format == Some(WordFormat::Bin) { "bin" } else { "mem" }));
    let format = format.unwrap_or(if out.extension().is_some_and(|e| e == "bin") { WordFormat::Bin } else { WordFormat::Mem });
    let bytes = match format {
        WordFormat::Mem => to_mem(&words).into_bytes(),
        WordFormat::Bin => to_bin(&words),
    };
    std::fs::write(&out, bytes).with_context(|| format!("cannot write {}", out.display()))?;
    eprintln!("{} words -> {}", words.len(), out.display());
    Ok(())
}

/// Reads a word file: `.mem`/`.hex` text, otherwise raw big-endian binary.
pub fn read_words(path: &Path) -> Result<Vec<u32>> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
    if ext == "mem" || ext == "hex" {
        let text = String::from_utf8(bytes).map_err(|_| anyhow::anyhow!("{}: not a text .mem file", path.display()))?;
        from_mem(&text).map_err(|e| anyhow::anyhow!("{}:{e}", path.display()))
    } else {
        from_bin(&bytes).map_err(|len| anyhow::anyhow!("{}: {len} bytes is not a whole number of 32-bit words", path.display()))
    }
}

pub fn disasm(path: &Path, camera_table: CameraTable, triangles: bool) -> Result<()> {
    let words = read_words(path)?;
    if looks_legacy(&words) {
        eprintln!("note: {} starts with a zero word followed by more program: this looks like REND3R's legacy ISA (nr = 0x00000000, nf = 0x00000200); shown here as the final ISA", path.display());
    }
    let set_table = if triangles { SetTable::Triangle } else { SetTable::Shape };
    match disassemble(&words, DisasmOptions { camera_table, set_table }) {
        Ok(text) => {
            print!("{text}");
            Ok(())
        }
        Err(e) => bail!("{}: {e}", path.display()),
    }
}
