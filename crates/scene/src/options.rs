//! How scene files are read.

/// How scene files are read.
#[derive(Clone, Copy, Debug, Default)]
pub struct LoadOptions {
    /// Refuse a glTF file that breaks any rule of the specification (what the Khronos
    /// validator calls an error), naming the JSON pointer. Off: lucent warns about the
    /// first broken rule and reads what it can (it still refuses what it cannot read
    /// safely: bad references, sizes, formats, containers).
    pub strict: bool,
}
