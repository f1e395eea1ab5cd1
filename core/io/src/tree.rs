//! A lossless in-memory copy of an HDF5 file's groups, datasets and attributes, so a dataset can
//! be read, edited and written back with every value, type and attribute intact.
//!
//! Each HDF5 element type is read and written here side by side, so that a type the reader
//! accepts is one the writer gives back unchanged.

use std::collections::BTreeMap;

use hdf5::types::{FixedAscii, FloatSize, IntSize, TypeDescriptor, VarLenAscii, VarLenUnicode};

use crate::error::{IoError, Result};

/// Longest fixed-length string this crate reads or writes (robomimic masks hold demo names).
pub const MAX_FIXED_STR: usize = 256;
type FixedStr = FixedAscii<MAX_FIXED_STR>;

/// Typed values of one dataset or attribute, row-major.
#[derive(Debug, Clone, PartialEq)]
#[allow(missing_docs)] // variant names are the HDF5 element types
pub enum Values {
    F64(Vec<f64>),
    F32(Vec<f32>),
    I64(Vec<i64>),
    I32(Vec<i32>),
    I16(Vec<i16>),
    I8(Vec<i8>),
    U64(Vec<u64>),
    U32(Vec<u32>),
    U16(Vec<u16>),
    U8(Vec<u8>),
    Bool(Vec<bool>),
    /// Variable-length UTF-8 strings (what h5py writes for Python `str`).
    Utf8(Vec<String>),
    /// Variable-length ASCII strings.
    Ascii(Vec<String>),
    /// Fixed-length byte strings of `len` bytes (numpy `S<len>`, robomimic masks).
    Fixed {
        /// Bytes per string.
        len: usize,
        /// The strings, without padding.
        strings: Vec<String>,
    },
}

impl Values {
    /// Number of elements.
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Self::F64(v) => v.len(),
            Self::F32(v) => v.len(),
            Self::I64(v) => v.len(),
            Self::I32(v) => v.len(),
            Self::I16(v) => v.len(),
            Self::I8(v) => v.len(),
            Self::U64(v) => v.len(),
            Self::U32(v) => v.len(),
            Self::U16(v) => v.len(),
            Self::U8(v) => v.len(),
            Self::Bool(v) => v.len(),
            Self::Utf8(v) | Self::Ascii(v) | Self::Fixed { strings: v, .. } => v.len(),
        }
    }

    /// True when there are no elements.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The numbers as `f64` (integers and booleans converted); `None` for strings.
    #[must_use]
    #[allow(clippy::cast_precision_loss)] // counts and ids are far below 2^53
    pub fn to_f64(&self) -> Option<Vec<f64>> {
        Some(match self {
            Self::F64(v) => v.clone(),
            Self::F32(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Self::I64(v) => v.iter().map(|&x| x as f64).collect(),
            Self::I32(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Self::I16(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Self::I8(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Self::U64(v) => v.iter().map(|&x| x as f64).collect(),
            Self::U32(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Self::U16(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Self::U8(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Self::Bool(v) => v.iter().map(|&x| f64::from(u8::from(x))).collect(),
            Self::Utf8(_) | Self::Ascii(_) | Self::Fixed { .. } => return None,
        })
    }

    /// Integer values as `i64` (booleans as 0/1); `None` for floats, strings and `u64` beyond `i64`.
    #[must_use]
    pub fn to_i64(&self) -> Option<Vec<i64>> {
        Some(match self {
            Self::I64(v) => v.clone(),
            Self::I32(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Self::I16(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Self::I8(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Self::U64(v) => v.iter().map(|&x| i64::try_from(x).ok()).collect::<Option<Vec<_>>>()?,
            Self::U32(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Self::U16(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Self::U8(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Self::Bool(v) => v.iter().map(|&x| i64::from(x)).collect(),
            _ => return None,
        })
    }

    /// The strings, for any string type; `None` for numbers.
    #[must_use]
    pub fn strings(&self) -> Option<&[String]> {
        match self {
            Self::Utf8(v) | Self::Ascii(v) | Self::Fixed { strings: v, .. } => Some(v),
            _ => None,
        }
    }

    /// A short type name (`float64`, `int64`, `str`, `S8`) as numpy would print it.
    #[must_use]
    pub fn dtype_name(&self) -> String {
        match self {
            Self::F64(_) => "float64".into(),
            Self::F32(_) => "float32".into(),
            Self::I64(_) => "int64".into(),
            Self::I32(_) => "int32".into(),
            Self::I16(_) => "int16".into(),
            Self::I8(_) => "int8".into(),
            Self::U64(_) => "uint64".into(),
            Self::U32(_) => "uint32".into(),
            Self::U16(_) => "uint16".into(),
            Self::U8(_) => "uint8".into(),
            Self::Bool(_) => "bool".into(),
            Self::Utf8(_) | Self::Ascii(_) => "str".into(),
            Self::Fixed { len, .. } => format!("S{len}"),
        }
    }
}

/// An n-dimensional array: shape plus row-major values. A scalar has an empty shape.
#[derive(Debug, Clone, PartialEq)]
pub struct Array {
    /// Extent of each dimension (empty for a scalar).
    pub shape: Vec<usize>,
    /// The values, row-major.
    pub values: Values,
}

impl Array {
    /// A scalar UTF-8 string (h5py's type for a Python `str` attribute).
    #[must_use]
    pub fn string(s: &str) -> Self {
        Self { shape: Vec::new(), values: Values::Utf8(vec![s.to_owned()]) }
    }

    /// A scalar `int64`.
    #[must_use]
    pub fn int(v: i64) -> Self {
        Self { shape: Vec::new(), values: Values::I64(vec![v]) }
    }

    /// A `float64` array.
    #[must_use]
    pub fn f64(shape: Vec<usize>, data: Vec<f64>) -> Self {
        Self { shape, values: Values::F64(data) }
    }

    /// An `int64` array.
    #[must_use]
    pub fn i64(shape: Vec<usize>, data: Vec<i64>) -> Self {
        Self { shape, values: Values::I64(data) }
    }

    /// The first string, when this is a string array or scalar.
    #[must_use]
    pub fn as_str(&self) -> Option<&str> {
        self.values.strings().and_then(|s| s.first()).map(String::as_str)
    }

    /// The first value as an integer (numeric strings are parsed, as robomimic files sometimes
    /// store `total` as text).
    #[must_use]
    pub fn as_i64(&self) -> Option<i64> {
        if let Some(v) = self.values.to_i64() {
            return v.first().copied();
        }
        self.as_str().and_then(|s| s.trim().parse().ok())
    }
}

/// A dataset: its array, attributes and storage layout.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// The data.
    pub array: Array,
    /// Attributes by name.
    pub attrs: BTreeMap<String, Array>,
    /// Chunk shape, when chunked.
    pub chunks: Option<Vec<usize>>,
    /// gzip level, when deflate-compressed.
    pub deflate: Option<u8>,
}

impl Dataset {
    /// A contiguous dataset without attributes.
    #[must_use]
    pub fn new(array: Array) -> Self {
        Self { array, attrs: BTreeMap::new(), chunks: None, deflate: None }
    }
}

/// A member of a group.
#[derive(Debug, Clone, PartialEq)]
pub enum Node {
    /// A sub-group.
    Group(Group),
    /// A dataset.
    Dataset(Dataset),
}

/// A group: attributes and members, both by name.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Group {
    /// Attributes by name.
    pub attrs: BTreeMap<String, Array>,
    /// Members by name.
    pub members: BTreeMap<String, Node>,
}

impl Group {
    /// The member group `name`.
    #[must_use]
    pub fn group(&self, name: &str) -> Option<&Group> {
        match self.members.get(name) {
            Some(Node::Group(g)) => Some(g),
            _ => None,
        }
    }

    /// The member dataset `name`.
    #[must_use]
    pub fn dataset(&self, name: &str) -> Option<&Dataset> {
        match self.members.get(name) {
            Some(Node::Dataset(d)) => Some(d),
            _ => None,
        }
    }

    /// The dataset at a `/`-separated path below this group.
    #[must_use]
    pub fn dataset_at(&self, path: &str) -> Option<&Dataset> {
        let (dir, name) = path.rsplit_once('/').unwrap_or(("", path));
        let mut g = self;
        for part in dir.split('/').filter(|p| !p.is_empty()) {
            g = g.group(part)?;
        }
        g.dataset(name)
    }
}

/// Reads `path` from `file_label` into a [`Group`] tree (`group_path` names it in errors).
pub(crate) fn read_group(file: &str, group: &hdf5::Group, group_path: &str) -> Result<Group> {
    read_group_except(file, group, group_path, &[])
}

/// [`read_group`] leaving out the direct members named in `skip` (and everything below them).
pub(crate) fn read_group_except(file: &str, group: &hdf5::Group, group_path: &str, skip: &[&str]) -> Result<Group> {
    let err = |field: &str, e: &hdf5::Error| IoError::hdf5(file, group_path, field, e);
    let mut out = Group { attrs: read_attrs(file, group, group_path)?, members: BTreeMap::new() };
    for name in group.member_names().map_err(|e| err("", &e))? {
        if skip.contains(&name.as_str()) {
            continue;
        }
        let child = join(group_path, &name);
        let node = if let Ok(g) = group.group(&name) {
            Node::Group(read_group(file, &g, &child)?)
        } else {
            let ds = group.dataset(&name).map_err(|e| err(&name, &e))?;
            let array = read_array(file, group_path, &name, &ds)?;
            let deflate = ds.filters().iter().find_map(|f| match f {
                hdf5::filters::Filter::Deflate(level) => Some(*level),
                _ => None,
            });
            Node::Dataset(Dataset { array, attrs: read_attrs(file, &ds, &child)?, chunks: ds.chunk(), deflate })
        };
        out.members.insert(name, node);
    }
    Ok(out)
}

/// Reads `path`'s whole structure and every attribute's value (but no dataset's values), then its
/// demos as the app first reads them (without observations): the parts of a file where a damaged
/// header has crashed libhdf5 (see `fuzz/known_crashes/README.md`).
/// Run it in a child process before reading a file the user chose, so a crash ends the child, not
/// the app. Returns how many groups and datasets it walked.
///
/// # Errors
/// The first refusal, naming the file and the object.
pub fn vet(path: &std::path::Path) -> Result<usize> {
    /// Keeps `r`'s error when it is the first.
    fn keep(first: &mut Option<IoError>, r: Result<()>) {
        if let Err(e) = r {
            first.get_or_insert(e);
        }
    }
    /// Walks on past a refusal (the readers that come after may reach further: a file whose
    /// `data` attributes are refused can still crash in its demos), keeping the first one.
    fn walk(file: &str, group: &hdf5::Group, group_path: &str, first: &mut Option<IoError>) -> usize {
        // Twice: the app reads a file's top groups' attributes more than once (the whole file, then
        // demo by demo), and a failed listing can leave libhdf5's heap damaged for the next one.
        keep(first, read_attrs(file, group, group_path).map(drop));
        keep(first, read_attrs(file, group, group_path).map(drop));
        let names = match group.member_names() {
            Ok(names) => names,
            Err(e) => {
                keep(first, Err(IoError::hdf5(file, group_path, "", &e)));
                return 1;
            }
        };
        let mut walked = 1;
        for name in names {
            let child = join(group_path, &name);
            if let Ok(g) = group.group(&name) {
                walked += walk(file, &g, &child, first);
                continue;
            }
            walked += 1;
            match group.dataset(&name) {
                Ok(ds) => {
                    let dtype = ds.dtype().and_then(|t| t.to_descriptor()).map(drop);
                    keep(first, dtype.map_err(|e| IoError::hdf5(file, group_path, &name, &e)));
                    keep(first, read_attrs(file, &ds, &child).map(drop));
                }
                Err(e) => keep(first, Err(IoError::hdf5(file, group_path, &name, &e))),
            }
        }
        walked
    }
    // First as the app reads a file: names and attributes, and each demo's poses, actions, states
    // and signals (in libhdf5, what crashes can depend on what was read before).
    let streamed = crate::DemoReader::open_with(path, crate::ReadOptions::default()).and_then(|reader| {
        use crate::DemoSource as _;
        let reader = reader.without_observations();
        reader.demo_names().iter().try_for_each(|name| reader.load_demo(name).map(drop))
    });
    let h5 = IoError::open_h5(path)?;
    let mut first = streamed.err();
    let walked = walk(&path.display().to_string(), &h5, "/", &mut first);
    first.map_or(Ok(walked), Err)
}

/// Joins HDF5 path parts.
pub(crate) fn join(group: &str, name: &str) -> String {
    if group.is_empty() || group == "/" { name.to_owned() } else { format!("{group}/{name}") }
}

/// Reads only the attributes of a group.
pub(crate) fn read_group_attrs(file: &str, group: &hdf5::Group, group_path: &str) -> Result<BTreeMap<String, Array>> {
    read_attrs(file, group, group_path)
}

fn read_attrs(file: &str, loc: &hdf5::Location, loc_path: &str) -> Result<BTreeMap<String, Array>> {
    let mut attrs = BTreeMap::new();
    for name in loc.attr_names().map_err(|e| IoError::hdf5(file, loc_path, "", &e))? {
        let attr = loc.attr(&name).map_err(|e| IoError::hdf5(file, loc_path, &name, &e))?;
        attrs.insert(name.clone(), read_array(file, loc_path, &name, &attr)?);
    }
    Ok(attrs)
}

/// Reads one dataset or attribute with its own element type.
/// How many times its stored size an array may be in memory (see [`read_array`]).
const MAX_INFLATION: u64 = 4096;

pub(crate) fn read_array(file: &str, group: &str, field: &str, c: &hdf5::Container) -> Result<Array> {
    let err = |e: &hdf5::Error| IoError::hdf5(file, group, field, e);
    let desc = c.dtype().and_then(|t| t.to_descriptor()).map_err(|e| err(&e))?;
    // A damaged header can claim more elements than the file stores (we saw 10^18 bytes): refuse
    // before the reader allocates them. Compression can make a dataset this much larger in memory
    // than on disk (deflate stops near 1000:1); small ones may be all fill value.
    let claimed = c.shape().iter().try_fold(desc.size() as u64, |bytes, &d| bytes.checked_mul(d as u64));
    let stored = c.storage_size();
    if claimed.is_none_or(|bytes| bytes > stored.saturating_mul(MAX_INFLATION).saturating_add(1 << 20)) {
        return Err(IoError::Invalid {
            file: file.to_owned(),
            group: group.to_owned(),
            field: field.to_owned(),
            reason: format!(
                "claims shape {:?} of {}-byte elements, but the file stores {stored} bytes of it: the file is damaged",
                c.shape(),
                desc.size()
            ),
        });
    }
    let r = c.as_reader();
    let values = match desc {
        TypeDescriptor::Float(FloatSize::U8) => Values::F64(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::Float(FloatSize::U4) => Values::F32(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::Integer(IntSize::U8) => Values::I64(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::Integer(IntSize::U4) => Values::I32(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::Integer(IntSize::U2) => Values::I16(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::Integer(IntSize::U1) => Values::I8(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::Unsigned(IntSize::U8) => Values::U64(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::Unsigned(IntSize::U4) => Values::U32(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::Unsigned(IntSize::U2) => Values::U16(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::Unsigned(IntSize::U1) => Values::U8(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::Boolean => Values::Bool(r.read_raw().map_err(|e| err(&e))?),
        TypeDescriptor::VarLenUnicode => {
            let v: Vec<VarLenUnicode> = r.read_raw().map_err(|e| err(&e))?;
            Values::Utf8(v.iter().map(|s| s.as_str().to_owned()).collect())
        }
        TypeDescriptor::VarLenAscii => {
            let v: Vec<VarLenAscii> = r.read_raw().map_err(|e| err(&e))?;
            Values::Ascii(v.iter().map(|s| s.as_str().to_owned()).collect())
        }
        TypeDescriptor::FixedAscii(len) | TypeDescriptor::FixedUnicode(len) if len <= MAX_FIXED_STR => {
            let v: Vec<FixedStr> = r.read_raw().map_err(|e| err(&e))?;
            Values::Fixed { len, strings: v.iter().map(|s| s.as_str().to_owned()).collect() }
        }
        other => {
            return Err(IoError::Invalid {
                file: file.to_owned(),
                group: group.to_owned(),
                field: field.to_owned(),
                reason: format!("unsupported HDF5 element type {other:?}"),
            });
        }
    };
    Ok(Array { shape: c.shape(), values })
}

/// Writes a [`Group`] tree's members and attributes into `group`.
pub(crate) fn write_group(file: &str, group: &hdf5::Group, group_path: &str, tree: &Group) -> Result<()> {
    write_attrs(file, group, group_path, &tree.attrs)?;
    for (name, node) in &tree.members {
        let child = join(group_path, name);
        match node {
            Node::Group(g) => {
                let sub = group.create_group(name).map_err(|e| IoError::hdf5_write(file, group_path, name, &e))?;
                write_group(file, &sub, &child, g)?;
            }
            Node::Dataset(d) => {
                let ds = write_dataset(file, group, group_path, name, d)?;
                write_attrs(file, &ds, &child, &d.attrs)?;
            }
        }
    }
    Ok(())
}

/// Writes attributes onto an object.
pub(crate) fn write_attrs(file: &str, loc: &hdf5::Location, loc_path: &str, attrs: &BTreeMap<String, Array>) -> Result<()> {
    for (name, a) in attrs {
        write_attr(file, loc, loc_path, name, a)?;
    }
    Ok(())
}

macro_rules! write_typed {
    ($builder:expr, $values:expr, $shape:expr, $name:expr) => {{
        let created = $builder.shape($shape.clone()).create($name)?;
        created.as_writer().write_raw(&$values[..])?;
        Ok(created)
    }};
}

fn dispatch<F, O>(values: &Values, mut f: F) -> hdf5::Result<O>
where
    F: FnMut(&dyn WriteValues) -> hdf5::Result<O>,
{
    match values {
        Values::F64(v) => f(v),
        Values::F32(v) => f(v),
        Values::I64(v) => f(v),
        Values::I32(v) => f(v),
        Values::I16(v) => f(v),
        Values::I8(v) => f(v),
        Values::U64(v) => f(v),
        Values::U32(v) => f(v),
        Values::U16(v) => f(v),
        Values::U8(v) => f(v),
        Values::Bool(v) => f(v),
        Values::Utf8(v) => {
            let s = v
                .iter()
                .map(|s| s.parse::<VarLenUnicode>())
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| hdf5::Error::from(e.to_string().as_str()))?;
            f(&s)
        }
        Values::Ascii(v) => {
            let s = v
                .iter()
                .map(VarLenAscii::from_ascii)
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| hdf5::Error::from(e.to_string().as_str()))?;
            f(&s)
        }
        Values::Fixed { len, strings } => {
            if *len > MAX_FIXED_STR || strings.iter().any(|s| s.len() > *len) {
                return Err(hdf5::Error::from(
                    format!("fixed strings of {len} bytes (at most {MAX_FIXED_STR}) cannot hold the values").as_str(),
                ));
            }
            let s = strings
                .iter()
                .map(FixedStr::from_ascii)
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| hdf5::Error::from(e.to_string().as_str()))?;
            f(&FixedWrite { len: *len, strings: s })
        }
    }
}

/// Object-safe writing of a typed buffer as a dataset or attribute.
trait WriteValues {
    fn dataset(&self, group: &hdf5::Group, name: &str, d: &Dataset) -> hdf5::Result<hdf5::Dataset>;
    fn attr(&self, loc: &hdf5::Location, name: &str, shape: &[usize]) -> hdf5::Result<hdf5::Attribute>;
}

impl<T: hdf5::H5Type> WriteValues for Vec<T> {
    fn dataset(&self, group: &hdf5::Group, name: &str, d: &Dataset) -> hdf5::Result<hdf5::Dataset> {
        let mut b = group.new_dataset::<T>();
        if let Some(c) = &d.chunks {
            b = b.chunk(c.clone());
        }
        if let Some(level) = d.deflate {
            b = b.deflate(level);
        }
        write_typed!(b, self, d.array.shape, name)
    }

    fn attr(&self, loc: &hdf5::Location, name: &str, shape: &[usize]) -> hdf5::Result<hdf5::Attribute> {
        let b = loc.new_attr::<T>();
        write_typed!(b, self, shape.to_vec(), name)
    }
}

/// Fixed-length strings written with their own on-disk length.
struct FixedWrite {
    len: usize,
    strings: Vec<FixedStr>,
}

impl WriteValues for FixedWrite {
    fn dataset(&self, group: &hdf5::Group, name: &str, d: &Dataset) -> hdf5::Result<hdf5::Dataset> {
        let mut b = group.new_dataset_builder().empty_as(TypeDescriptor::FixedAscii(self.len));
        if let Some(c) = &d.chunks {
            b = b.chunk(c.clone());
        }
        if let Some(level) = d.deflate {
            b = b.deflate(level);
        }
        write_typed!(b, self.strings, d.array.shape, name)
    }

    fn attr(&self, loc: &hdf5::Location, name: &str, shape: &[usize]) -> hdf5::Result<hdf5::Attribute> {
        let b = loc.new_attr_builder().empty_as(TypeDescriptor::FixedAscii(self.len));
        write_typed!(b, self.strings, shape.to_vec(), name)
    }
}

fn check_len(file: &str, group: &str, field: &str, a: &Array) -> Result<()> {
    let expected: usize = a.shape.iter().product();
    if expected != a.values.len() {
        return Err(IoError::Usage {
            file: file.to_owned(),
            group: group.to_owned(),
            field: field.to_owned(),
            reason: format!("shape {:?} needs {expected} values, got {}", a.shape, a.values.len()),
        });
    }
    Ok(())
}

/// Writes one dataset (without its attributes).
pub(crate) fn write_dataset(file: &str, group: &hdf5::Group, group_path: &str, name: &str, d: &Dataset) -> Result<hdf5::Dataset> {
    check_len(file, group_path, name, &d.array)?;
    dispatch(&d.array.values, |w| w.dataset(group, name, d)).map_err(|e| IoError::hdf5_write(file, group_path, name, &e))
}

/// Writes one attribute.
pub(crate) fn write_attr(file: &str, loc: &hdf5::Location, loc_path: &str, name: &str, a: &Array) -> Result<()> {
    check_len(file, loc_path, name, a)?;
    dispatch(&a.values, |w| w.attr(loc, name, &a.shape)).map(drop).map_err(|e| IoError::hdf5_write(file, loc_path, name, &e))
}
