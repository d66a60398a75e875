//! glTF accessors read with every bound checked: the element size from the
//! component type and count, the buffer view's stride, offset and length,
//! and the buffer's loaded bytes, so that a file whose accessor reaches past
//! its data is an error naming the accessor, never a panic or a read of the
//! wrong bytes. Sparse accessors are applied over their base (or zeros).
//! Integer components are converted to `f32` as the glTF 2.0 spec says
//! (section 3.11, "normalized": `u8/255`, `u16/65535`, `max(i8/127, −1)`,
//! `max(i16/32767, −1)`); unnormalised integers keep their value.

use gltf::accessor::{DataType, Dimensions};
use gltf::Accessor;

/// The most elements an accessor without a buffer view (all zeros, perhaps
/// with sparse values) may declare: it has no data to bound it, and a count
/// of 2^40 would otherwise allocate before anything else failed.
pub const MAX_ELEMENTS_WITHOUT_DATA: usize = 1 << 24;

/// The loaded bytes of each buffer, in the file's order.
pub struct Buffers(pub Vec<Vec<u8>>);

/// Bytes of one component of `t`.
fn component_size(t: DataType) -> usize {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

/// Components per element; matrices are refused (no vertex data uses them).
fn components(d: Dimensions) -> Option<usize> {
    match d {
        Dimensions::Scalar => Some(1),
        Dimensions::Vec2 => Some(2),
        Dimensions::Vec3 => Some(3),
        Dimensions::Vec4 => Some(4),
        _ => None,
    }
}

/// Component `k` of the element at `bytes` as `f64` (normalised when asked).
fn component(bytes: &[u8], t: DataType, normalized: bool, k: usize) -> f64 {
    let at = k * component_size(t);
    let b = &bytes[at..at + component_size(t)];
    match t {
        DataType::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        DataType::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        DataType::U8 => {
            let v = f64::from(b[0]);
            if normalized {
                v / 255.0
            } else {
                v
            }
        }
        DataType::U16 => {
            let v = f64::from(u16::from_le_bytes([b[0], b[1]]));
            if normalized {
                v / 65535.0
            } else {
                v
            }
        }
        DataType::I8 => {
            let v = f64::from(b[0] as i8);
            if normalized {
                (v / 127.0).max(-1.0)
            } else {
                v
            }
        }
        DataType::I16 => {
            let v = f64::from(i16::from_le_bytes([b[0], b[1]]));
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
    }
}

/// The bytes of buffer view `view` (checked against the loaded buffer).
fn view_bytes<'b>(view: &gltf::buffer::View, buffers: &'b Buffers) -> Result<&'b [u8], String> {
    let b = view.buffer().index();
    let data = buffers.0.get(b).ok_or_else(|| {
        format!(
            "bufferView {} names buffer {b}, which was not loaded",
            view.index()
        )
    })?;
    let (start, len) = (view.offset() as u64, view.length() as u64);
    let end = start + len;
    if end > data.len() as u64 {
        return Err(format!(
            "bufferView {} spans bytes {start}..{end} of buffer {b}, which has {} bytes",
            view.index(),
            data.len()
        ));
    }
    Ok(&data[start as usize..end as usize])
}

/// `count` elements of `elem` bytes at `offset` in `bytes` with `stride`
/// (0: tightly packed): the byte slice of element `i` for each.
fn strided<'b>(
    bytes: &'b [u8],
    offset: usize,
    count: usize,
    elem: usize,
    stride: Option<usize>,
    what: &str,
) -> Result<Vec<&'b [u8]>, String> {
    let stride = stride.unwrap_or(elem);
    if stride < elem {
        return Err(format!(
            "{what}: byteStride {stride} is smaller than its element ({elem} bytes)"
        ));
    }
    if count == 0 {
        return Ok(Vec::new());
    }
    let need = (offset as u128) + (stride as u128) * (count as u128 - 1) + elem as u128;
    if need > bytes.len() as u128 {
        return Err(format!(
            "{what}: {count} elements of {elem} bytes (stride {stride}) from byte {offset} need \
             {need} bytes of its bufferView, which has {}",
            bytes.len()
        ));
    }
    Ok((0..count)
        .map(|i| &bytes[offset + i * stride..offset + i * stride + elem])
        .collect())
}

/// Reads accessor `a` as `N`-component float vectors (`Dimensions` must
/// give `N` components). `what` names it in errors (`"meshes[0]
/// .primitives[1] POSITION"`).
pub fn read_vectors<const N: usize>(
    a: &Accessor,
    buffers: &Buffers,
    what: &str,
) -> Result<Vec<[f64; N]>, String> {
    let what = format!("{what} (accessor {})", a.index());
    let dims = components(a.dimensions());
    if dims != Some(N) {
        return Err(format!(
            "{what}: type {:?}, expected {N} component(s)",
            a.dimensions()
        ));
    }
    let t = a.data_type();
    let elem = N * component_size(t);
    let count = a.count();
    let decode = |bytes: &[u8]| -> [f64; N] {
        std::array::from_fn(|k| component(bytes, t, a.normalized(), k))
    };
    let mut out: Vec<[f64; N]> = match a.view() {
        Some(view) => {
            let bytes = view_bytes(&view, buffers).map_err(|e| format!("{what}: {e}"))?;
            strided(bytes, a.offset(), count, elem, view.stride(), &what)?
                .into_iter()
                .map(decode)
                .collect()
        }
        None => {
            if count > MAX_ELEMENTS_WITHOUT_DATA {
                return Err(format!(
                    "{what}: {count} elements without a bufferView (more than \
                     {MAX_ELEMENTS_WITHOUT_DATA})"
                ));
            }
            vec![[0.0; N]; count]
        }
    };
    if let Some(sparse) = a.sparse() {
        let n = sparse.count();
        let idx = sparse.indices();
        let it = match idx.index_type() {
            gltf::accessor::sparse::IndexType::U8 => DataType::U8,
            gltf::accessor::sparse::IndexType::U16 => DataType::U16,
            gltf::accessor::sparse::IndexType::U32 => DataType::U32,
        };
        let ibytes = view_bytes(&idx.view(), buffers).map_err(|e| format!("{what}: {e}"))?;
        let indices = strided(
            ibytes,
            idx.offset(),
            n,
            component_size(it),
            None,
            &format!("{what} sparse indices"),
        )?;
        let vals = sparse.values();
        let vbytes = view_bytes(&vals.view(), buffers).map_err(|e| format!("{what}: {e}"))?;
        let values = strided(
            vbytes,
            vals.offset(),
            n,
            elem,
            None,
            &format!("{what} sparse values"),
        )?;
        for (i, v) in indices.into_iter().zip(values) {
            let i = component(i, it, false, 0) as usize;
            let slot = out
                .get_mut(i)
                .ok_or_else(|| format!("{what}: sparse index {i} is past its {count} elements"))?;
            *slot = decode(v);
        }
    }
    Ok(out)
}

/// Reads an index accessor (scalar `u8`, `u16` or `u32`), each index below
/// `vertices`.
pub fn read_indices(
    a: &Accessor,
    buffers: &Buffers,
    vertices: usize,
    what: &str,
) -> Result<Vec<u32>, String> {
    let label = format!("{what} (accessor {})", a.index());
    if !matches!(a.data_type(), DataType::U8 | DataType::U16 | DataType::U32)
        || a.dimensions() != Dimensions::Scalar
    {
        return Err(format!(
            "{label}: indices must be scalar u8, u16 or u32, found {:?} {:?}",
            a.dimensions(),
            a.data_type()
        ));
    }
    let values = read_vectors::<1>(a, buffers, what)?;
    values
        .into_iter()
        .enumerate()
        .map(|(k, [v])| {
            if (v as usize) < vertices {
                Ok(v as u32)
            } else {
                Err(format!(
                    "{label}: index {k} is {v}, past the primitive's {vertices} vertices"
                ))
            }
        })
        .collect()
}
