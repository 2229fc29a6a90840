//! pyo3 bindings of `rotorid-core`: array shapes checked and converted, output sizes checked
//! against the memory available, the GIL released while the core computes. The physics is in the
//! core crate, whose argument errors (`CoreError`) become `ValueError` here; any Rust panic would
//! become a `RuntimeError` (a panic never crosses into Python).

use rotorid_core::study::{self, Excitation, ImpactErrors, Method, Study, SyncErrors};
use rotorid_core::{forced, identify, modal, model, order, pedestal, pedestal_cov, revolution_blocks, series, timesim, CoreError, Rotor, C64};
use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyMemoryError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyList;
use std::borrow::Cow;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Mutex, OnceLock};

/// mimalloc keeps freed output buffers mapped, so repeated calls do not page-fault fresh memory
/// for every result array (glibc maps and unmaps blocks above its mmap threshold each time).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn slice<'a, T: numpy::Element>(a: &'a PyReadonlyArrayDyn<'_, T>, name: &str) -> PyResult<&'a [T]> {
    // (as_slice alone also accepts Fortran order, whose memory order the kernels would misread)
    if !a.is_c_contiguous() {
        return Err(PyValueError::new_err(format!("{name} must be a C-contiguous array")));
    }
    a.as_slice().map_err(|_| PyValueError::new_err(format!("{name} must be a C-contiguous array")))
}

fn check_shape(name: &str, got: &[usize], want: &[usize]) -> PyResult<()> {
    if got != want {
        return Err(PyValueError::new_err(format!("{name} has shape {got:?}, expected {want:?}")));
    }
    Ok(())
}

/// A real (2, 2) transform between two pairs of measurement planes (report eq. 19) as
/// [T11, T12, T21, T22].
fn plane_transform(name: &str, t: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<[f64; 4]> {
    check_shape(name, t.shape(), &[2, 2])?;
    slice(t, name)?.try_into().map_err(|_| PyValueError::new_err(format!("{name} must hold 4 values")))
}

fn guarded<T: Send, F: FnOnce() -> T + Send>(f: F) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(|| in_process_pool(f))).map_err(|e| {
        let msg = e
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "unknown".into());
        PyRuntimeError::new_err(format!("rotorid core failed internally (please report): {msg}"))
    })
}

/// The process that loaded the module. rayon's global pool belongs to it: after `fork()` the
/// child inherits the pool's state but none of its threads, and its first parallel call would
/// wait forever (Python's multiprocessing forks by default on Linux).
static LOADED_BY: OnceLock<u32> = OnceLock::new();
/// A thread pool of a forked child, built on its first parallel call.
static CHILD_POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);

/// Run `f` on rayon's global pool in the process that loaded the module, and on a pool of the
/// current process in a forked child (built once per child).
fn in_process_pool<T: Send, F: FnOnce() -> T + Send>(f: F) -> T {
    let me = std::process::id();
    if *LOADED_BY.get_or_init(|| me) == me {
        return f();
    }
    let pool = {
        let mut slot = CHILD_POOL.lock().unwrap_or_else(|p| p.into_inner());
        match slot.as_ref() {
            Some((pid, pool)) if *pid == me => pool.clone(),
            _ => {
                let threads = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
                let pool = Arc::new(
                    rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .expect("a thread pool for the forked process"),
                );
                *slot = Some((me, pool.clone()));
                pool
            }
        }
    };
    pool.install(f)
}

fn core_err(e: CoreError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

fn rotor_of(p: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<Rotor> {
    Rotor::from_slice(slice(p, "rotor")?).map_err(PyValueError::new_err)
}

/// An output buffer of `n` values that the kernels overwrite completely before anything reads it
/// (every kernel writes every output element of every point it owns: identification, relative
/// standard errors, resampling, run-out filter). Skipping the zero fill
/// saves a pass over memory that dominated small calls.
fn out_buf<T: Plain>(n: usize) -> Vec<T> {
    let mut v = Vec::with_capacity(n);
    // SAFETY: T (f64 or C64) has no invalid bit patterns, the capacity is n, and the kernels write
    // all n elements before the vector is read or handed to NumPy.
    #[allow(clippy::uninit_vec)]
    unsafe {
        v.set_len(n)
    };
    v
}

/// Element types whose every bit pattern is a value (an unwritten one is garbage, not undefined
/// behaviour), for [`out_buf`].
trait Plain: Copy {}
impl Plain for f64 {}
impl Plain for C64 {}

/// The values of a (n,) axis argument, or of a (1,) one repeated n times, and times `scale` when
/// given: Rust-owned when anything is to be done (a broadcast or a scale), so that the caller
/// passes an axis in its own unit (Hz with scale 2 pi) or one running speed instead of building
/// an (n,) NumPy temporary (each one freed by glibc back to the system, faulted in on the next
/// call); the caller's array as it is otherwise. A strided axis (a reversed run-down, a column of
/// a table) is read into a Rust-owned copy, with the same arithmetic.
fn axis_values<'a>(name: &str, a: &'a PyReadonlyArrayDyn<'_, f64>, n: usize, scale: Option<f64>) -> PyResult<Cow<'a, [f64]>> {
    let sh = a.shape();
    if sh != [n] && sh != [1] {
        return Err(PyValueError::new_err(format!("{name} has shape {sh:?}, expected ({n},) or (1,)")));
    }
    let v: Cow<'a, [f64]> = if a.is_c_contiguous() {
        Cow::Borrowed(slice(a, name)?)
    } else {
        Cow::Owned(a.as_array().iter().copied().collect())
    };
    Ok(match (v.len() == n, scale) {
        (true, None) => v,
        (true, Some(s)) => Cow::Owned(v.iter().map(|x| x * s).collect()),
        (false, s) => Cow::Owned(vec![v[0] * s.unwrap_or(1.0); n]),
    })
}

/// Refuse an output of `elems` elements of `elem_bytes` each before allocating it: a product that
/// overflows, or more than 80 % of the memory the system reports available, is a Python
/// MemoryError naming the function (an allocation failure would abort the interpreter, and with
/// overcommit a too-large buffer is only found out by the out-of-memory killer). Outputs below
/// [`ALLOC_CHECKED_FROM`] are not compared with the available memory: reading /proc/meminfo took
/// 10 µs of every core call, as long as a 1,000-point identification.
fn check_alloc(what: &str, elems: Option<usize>, elem_bytes: usize) -> PyResult<()> {
    let bytes = elems.and_then(|e| e.checked_mul(elem_bytes)).ok_or_else(|| {
        PyMemoryError::new_err(format!("{what}: the requested output does not fit in memory (size overflows)"))
    })?;
    if bytes < ALLOC_CHECKED_FROM {
        return Ok(());
    }
    if let Some(avail) = available_bytes() {
        if bytes as f64 > 0.8 * avail as f64 {
            return Err(PyMemoryError::new_err(format!(
                "{what}: the output would need {:.2} GB, {:.2} GB of memory are available; process fewer points at once",
                bytes as f64 / 1e9,
                avail as f64 / 1e9
            )));
        }
    }
    Ok(())
}

/// The smallest output (bytes) [`check_alloc`] compares with the available memory: any machine
/// that runs the interpreter has 64 MiB to spare, and larger outputs take milliseconds to fill.
const ALLOC_CHECKED_FROM: usize = 64 << 20;

/// MemAvailable from /proc/meminfo (Linux); None elsewhere.
fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

fn to_py<'py, T: numpy::Element>(py: Python<'py>, v: Vec<T>, shape: &[usize]) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    PyArray1::from_vec(py, v).reshape(shape.to_vec())
}

/// The argument shapes of a forced response (k, c (n or 1, 8); spin (n,); force (n or 1, nrhs >= 1,
/// 4); gain (n,)) and its output memory (`per_point` complex values per point and force vector);
/// returns nrhs.
#[allow(clippy::too_many_arguments)]
fn forced_shapes(
    what: &str,
    n: usize,
    k: &PyReadonlyArrayDyn<'_, f64>,
    c: &PyReadonlyArrayDyn<'_, f64>,
    spin: Option<&PyReadonlyArrayDyn<'_, f64>>,
    force: &PyReadonlyArrayDyn<'_, C64>,
    gain: Option<&PyReadonlyArrayDyn<'_, f64>>,
    per_point: usize,
) -> PyResult<usize> {
    for (name, a) in [("k", k), ("c", c)] {
        let sh = a.shape();
        if sh.len() != 2 || sh[1] != 8 || !(sh[0] == n || sh[0] == 1) {
            return Err(PyValueError::new_err(format!("{name} has shape {sh:?}, expected ({n} or 1, 8)")));
        }
    }
    if let Some(spin) = spin {
        check_shape("spin", spin.shape(), &[n])?;
    }
    let fs = force.shape().to_vec();
    if fs.len() != 3 || fs[2] != 4 || !(fs[0] == n || fs[0] == 1) {
        return Err(PyValueError::new_err(format!("force has shape {fs:?}, expected (n or 1, nrhs, 4)")));
    }
    let nrhs = fs[1];
    if nrhs == 0 {
        return Err(PyValueError::new_err("force has no force vectors (shape (n, 0, 4))"));
    }
    if let Some(g) = gain {
        check_shape("gain", g.shape(), &[n])?;
    }
    check_alloc(what, n.checked_mul(nrhs).and_then(|v| v.checked_mul(per_point)), 16)?;
    Ok(nrhs)
}

/// Batched forced response H q = F (see forced.rs); with `gain` (n,), q_i = gain_i H_i^-1 F
/// (an imbalance: F broadcast, gain = Omega^2). Returns (q, n_singular).
/// `spin` may be (1,) (one running speed); `w_scale`: w is `w_scale` times the given axis (e.g.
/// frequencies in Hz with 2 pi), formed here; `planes`: None, or the (2, 2) eq. 19 transform
/// applied to every solution (e.g. from the bearings to the probe planes) in the same pass.
#[pyfunction]
#[pyo3(signature = (rotor, k, c, spin, w, force, gain=None, w_scale=None, planes=None))]
#[allow(clippy::too_many_arguments)]
fn forced_response<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    k: PyReadonlyArrayDyn<'py, f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    spin: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    force: PyReadonlyArrayDyn<'py, C64>,
    gain: Option<PyReadonlyArrayDyn<'py, f64>>,
    w_scale: Option<f64>,
    planes: Option<PyReadonlyArrayDyn<'py, f64>>,
) -> PyResult<(Bound<'py, PyArrayDyn<C64>>, usize)> {
    let rot = rotor_of(&rotor)?;
    let n = w.len();
    let (ss, ws) = (axis_values("spin", &spin, n, None)?, axis_values("w", &w, n, w_scale)?);
    let nrhs = forced_shapes("forced_response", n, &k, &c, None, &force, gain.as_ref(), 4)?;
    let (ks, cs, fsl) = (slice(&k, "k")?, slice(&c, "c")?, slice(&force, "force")?);
    let (ss, ws) = (&ss[..], &ws[..]);
    let g = match &gain {
        Some(g) => forced::Gain::PerPoint(slice(g, "gain")?),
        None => forced::Gain::One,
    };
    let t = planes.as_ref().map(|t| plane_transform("planes", t)).transpose()?;
    let (out, nsing) = py.detach(|| {
        guarded(|| {
            let mut out = out_buf(n * nrhs * 4);
            forced::forced_response_with(&rot, ks, cs, ss, ws, fsl, nrhs, g, t.as_ref(), &mut out).map(|ns| (out, ns))
        })
    })?
    .map_err(core_err)?;
    Ok((to_py(py, out, &[n, nrhs, 4])?, nsing))
}

/// The synchronous response to an imbalance at the speeds `spin` (rad/s): w = spin and
/// q_i = spin_i^2 H_i^-1 force (see forced::forced_response_imbalance), without the (n,) arrays
/// of w and spin^2 the caller would otherwise build; `spin_scale`: spin is given in another unit
/// (rpm with pi / 30), converted here; `planes`: as for forced_response. Returns (q, n_singular).
#[pyfunction]
#[pyo3(signature = (rotor, k, c, spin, force, spin_scale=None, planes=None))]
#[allow(clippy::too_many_arguments)]
fn imbalance_response<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    k: PyReadonlyArrayDyn<'py, f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    spin: PyReadonlyArrayDyn<'py, f64>,
    force: PyReadonlyArrayDyn<'py, C64>,
    spin_scale: Option<f64>,
    planes: Option<PyReadonlyArrayDyn<'py, f64>>,
) -> PyResult<(Bound<'py, PyArrayDyn<C64>>, usize)> {
    let rot = rotor_of(&rotor)?;
    let n = spin.len();
    let nrhs = forced_shapes("imbalance_response", n, &k, &c, Some(&spin), &force, None, 4)?;
    let ss = axis_values("spin", &spin, n, spin_scale)?;
    let (ks, cs, ss, fsl) = (slice(&k, "k")?, slice(&c, "c")?, &ss[..], slice(&force, "force")?);
    let t = planes.as_ref().map(|t| plane_transform("planes", t)).transpose()?;
    let (out, nsing) = py.detach(|| {
        guarded(|| {
            let mut out = out_buf(n * nrhs * 4);
            forced::forced_response_with(&rot, ks, cs, ss, ss, fsl, nrhs, forced::Gain::SpinSquared, t.as_ref(), &mut out)
                .map(|ns| (out, ns))
        })
    })?
    .map_err(core_err)?;
    Ok((to_py(py, out, &[n, nrhs, 4])?, nsing))
}

/// Responses moved between measurement planes (report eq. 19, see model::apply_planes): t (2, 2)
/// real, q (..., 4) complex [x1, x2, y1, y2]; returns (an array of q's shape, the flat index of
/// q's first non-finite value or None).
#[pyfunction]
fn apply_planes<'py>(py: Python<'py>, t: PyReadonlyArrayDyn<'py, f64>, q: PyReadonlyArrayDyn<'py, C64>) -> PyResult<(Bound<'py, PyArrayDyn<C64>>, Option<usize>)> {
    let ts = plane_transform("t", &t)?;
    let shape = q.shape().to_vec();
    if shape.last() != Some(&4) {
        return Err(PyValueError::new_err(format!("q has shape {shape:?}, expected (..., 4)")));
    }
    let qs = slice(&q, "q")?;
    check_alloc("apply_planes", Some(qs.len()), 16)?;
    let out = py
        .detach(|| {
            guarded(|| {
                let mut out = out_buf(qs.len());
                model::apply_planes(&ts, qs, &mut out).map(|bad| (out, bad))
            })
        })?
        .map_err(core_err)?;
    Ok((to_py(py, out.0, &shape)?, out.1))
}

type IdentTuple<'py> = (
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
    Option<Bound<'py, PyArrayDyn<f64>>>,
    Option<Bound<'py, PyArrayDyn<f64>>>,
    Option<Bound<'py, PyArrayDyn<f64>>>,
    Option<Bound<'py, PyArrayDyn<u8>>>,
    Option<Bound<'py, PyArrayDyn<f64>>>,
    Option<Bound<'py, PyArrayDyn<bool>>>,
    usize,
);

/// The arrays of a Python list, each of element type `T` (`dtype` names it in the message),
/// refused by position: "`name`[r] must be a `dtype` array".
fn list_arrays<'py, T: numpy::Element>(list: &Bound<'py, PyList>, name: &str, dtype: &str) -> PyResult<Vec<PyReadonlyArrayDyn<'py, T>>> {
    list.iter()
        .enumerate()
        .map(|(r, a)| a.extract().map_err(|_| PyTypeError::new_err(format!("{name}[{r}] must be a {dtype} array"))))
        .collect()
}

/// One slice per array of [`list_arrays`], named `name`[r] in a contiguity error.
fn list_slices<'a, T: numpy::Element>(arrays: &'a [PyReadonlyArrayDyn<'_, T>], name: &str) -> PyResult<Vec<&'a [T]>> {
    arrays.iter().enumerate().map(|(r, a)| slice(a, &format!("{name}[{r}]"))).collect()
}

/// The responses of an identification as (batch, runs) blocks of (n, 4): either one array
/// (batch, runs, n, 4) or a list of `runs` arrays (n, 4) of one problem, used where they are.
struct Responses<'py> {
    arrays: Vec<PyReadonlyArrayDyn<'py, C64>>,
    /// one array (batch, runs, n, 4) rather than a list of runs
    stacked: bool,
    batch: usize,
    runs: usize,
    n: usize,
}

fn responses<'py>(q: &Bound<'py, PyAny>) -> PyResult<Responses<'py>> {
    if let Ok(list) = q.cast::<PyList>() {
        let arrays: Vec<PyReadonlyArrayDyn<'py, C64>> = list_arrays(list, "q", "complex128")?;
        let n = arrays.first().map(|a| a.shape()[0]).unwrap_or(0);
        for (r, a) in arrays.iter().enumerate() {
            if a.shape() != [n, 4] {
                return Err(PyValueError::new_err(format!("q[{r}] has shape {:?}, expected ({n}, 4)", a.shape())));
            }
        }
        let runs = arrays.len();
        return Ok(Responses { arrays, stacked: false, batch: 1, runs, n });
    }
    let a: PyReadonlyArrayDyn<'py, C64> = q.extract().map_err(|_| PyTypeError::new_err("q must be a complex128 array or a list of them"))?;
    let qs = a.shape().to_vec();
    if qs.len() != 4 || qs[3] != 4 {
        return Err(PyValueError::new_err(format!("q has shape {qs:?}, expected (batch, runs, n, 4)")));
    }
    Ok(Responses { arrays: vec![a], stacked: true, batch: qs[0], runs: qs[1], n: qs[2] })
}

impl Responses<'_> {
    fn blocks(&self) -> PyResult<Vec<&[C64]>> {
        if self.stacked {
            let all = slice(&self.arrays[0], "q")?;
            let step = 4 * self.n;
            return Ok(if step == 0 { vec![&all[..0]; self.batch * self.runs] } else { all.chunks(step).collect() });
        }
        self.arrays.iter().map(|a| slice(a, "every q[r]")).collect()
    }
}

/// Pedestal motions laid out as the responses `resp` (same batch, runs and points), or None.
fn pedestal_responses<'py>(q_ped: Option<&Bound<'py, PyAny>>, resp: &Responses<'py>) -> PyResult<Option<Responses<'py>>> {
    let Some(qp) = q_ped else { return Ok(None) };
    if qp.is_none() {
        return Ok(None);
    }
    let pr = responses(qp).map_err(|e| PyValueError::new_err(format!("q_ped: {e}")))?;
    if (pr.batch, pr.runs, pr.n) != (resp.batch, resp.runs, resp.n) {
        return Err(PyValueError::new_err(format!(
            "q_ped has (batch, runs, points) = ({}, {}, {}), q has ({}, {}, {})",
            pr.batch, pr.runs, pr.n, resp.batch, resp.runs, resp.n
        )));
    }
    Ok(Some(pr))
}

/// The blocks of the pedestal motion, or none for rigid pedestals.
fn pedestal_blocks<'a>(ped: &'a Option<Responses<'_>>) -> PyResult<Vec<&'a [C64]>> {
    match ped {
        Some(pr) => pr.blocks(),
        None => Ok(Vec::new()),
    }
}

/// `method` "report" (the report's 16-unknown formulation: true) or "forces" (false).
fn report_method(method: &str) -> PyResult<bool> {
    match method {
        "forces" => Ok(false),
        "report" => Ok(true),
        other => Err(PyValueError::new_err(format!("method must be 'forces' or 'report', got {other:?}"))),
    }
}

/// The checked identification problem of `identify`'s arguments, bound to `$prob` in the
/// caller's block (with the responses as `$resp`): the pieces it borrows (axis values, blocks of
/// q and of the pedestal motion) live in that block too, which a function returning the problem
/// could not give them.
macro_rules! ident_problem_of {
    ($prob:ident, $resp:ident; $rot:expr, $q:expr, $q_ped:expr, $w:expr, $sigma:expr, $w_scale:expr, $spin:expr, $e:expr, $gain:expr, $planes:expr, $identical:expr) => {
        let $resp = responses($q)?;
        let axes = AxisValues::new($w, $sigma, $resp.n, $w_scale)?;
        let blocks = $resp.blocks()?;
        let ped = pedestal_responses($q_ped, &$resp)?;
        let ped_blocks = pedestal_blocks(&ped)?;
        let $prob = ident_problem($rot, &$resp, &axes, $spin, $e, $gain, &blocks, &ped_blocks, $planes, $identical)?;
    };
}

/// Batched identification (see rotorid_core::identify).
/// q: (B, R, n, 4) complex, or a list of R arrays (n, 4) for B = 1; e: (1 or B, R, 4) complex;
/// w, spin: (n,) (spin also (1,)); spin None: spin = w (synchronous runs, after `w_scale`);
/// gain: (n,), (1,) or None (spin^2: an imbalance); planes: None, or the (2, 2)
/// eq. 19 transform from the planes q was measured at to the bearings. method: "forces" (default solver) or "report" (16-unknown real
/// formulation). Returns (k, c, cond, resid, amp, k_std, c_std, rel_std, flag_code, rel_amp, ok,
/// n_nonfinite) with k, c: (B, n, 2, 2, 2), cond (B, n, 2), resid, amp (rms response amplitude)
/// and rel_std (largest standard error relative to the bearing's direct coefficients, see
/// identify::relative_std) (B, n). `flag_limits` (cond_max, min_rel_amplitude, max_rel_std, dof)
/// (dof: the degrees of freedom of the standard errors, for the negative-damping test):
/// also the flag codes (uint8), amp / max amp and ok = (code == 0) of each batch row (B, n), as
/// `flag_codes` gives them, computed in the same call (None otherwise); "uncertain" only when standard errors are
/// computed. `refine_all`: the refinement step of the semi-normal equations in every point, not
/// only from cond = REFINE_COND on (how the uncertainty propagation's central differences solve).
#[pyfunction]
#[pyo3(name = "identify", signature = (rotor, w, spin, q, e, gain, identical=false, method="forces", with_std=true, sigma=None, q_ped=None, planes=None, w_scale=None, flag_limits=None, refine_all=false))]
#[allow(clippy::too_many_arguments)]
fn py_identify<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    spin: Option<PyReadonlyArrayDyn<'py, f64>>,
    q: &Bound<'py, PyAny>,
    e: PyReadonlyArrayDyn<'py, C64>,
    gain: Option<PyReadonlyArrayDyn<'py, f64>>,
    identical: bool,
    method: &str,
    with_std: bool,
    sigma: Option<PyReadonlyArrayDyn<'py, f64>>,
    q_ped: Option<&Bound<'py, PyAny>>,
    planes: Option<PyReadonlyArrayDyn<'py, f64>>,
    w_scale: Option<f64>,
    flag_limits: Option<&Bound<'py, PyAny>>,
    refine_all: bool,
) -> PyResult<IdentTuple<'py>> {
    let flag_limits = flag_limits
        .map(|f| f.extract::<(f64, f64, f64, f64)>())
        .transpose()
        .map_err(|e| PyValueError::new_err(format!("flag_limits must be (cond_max, min_rel_amplitude, max_rel_std, dof): {e}")))?;
    let rot = rotor_of(&rotor)?;
    let report = report_method(method)?;
    ident_problem_of!(prob, resp; rot, q, q_ped, &w, &sigma, w_scale, spin.as_ref(), &e, &gain, planes.as_ref(), identical);
    let (batch, n) = (resp.batch, resp.n);
    let npts = batch.checked_mul(n).ok_or_else(|| PyMemoryError::new_err("identify: batch x points overflows"))?;
    let want_std = with_std && !report;
    check_alloc("identify", npts.checked_mul(if want_std { 37 } else { 20 }), 8)?;
    let res = py.detach(|| {
        guarded(|| {
            let mut k = out_buf(npts * 8);
            let mut c = out_buf(npts * 8);
            let mut cond = out_buf(npts * 2);
            let mut resid = out_buf(npts);
            let mut amp = out_buf(npts);
            let mut ks = if want_std { out_buf(npts * 8) } else { Vec::new() };
            let mut cs = if want_std { out_buf(npts * 8) } else { Vec::new() };
            let mut rel = if want_std { out_buf(npts) } else { Vec::new() };
            let out = identify::IdentOut {
                k: &mut k,
                c: &mut c,
                cond: &mut cond,
                resid: &mut resid,
                amp: &mut amp,
                k_std: if want_std { Some(&mut ks[..]) } else { None },
                c_std: if want_std { Some(&mut cs[..]) } else { None },
                rel_std: if want_std { Some(&mut rel[..]) } else { None },
            };
            let refine_cond = if refine_all { 0.0 } else { identify::REFINE_COND };
            let nbad = if report { identify::identify_report(&prob, out) } else { identify::identify_forces_refined(&prob, out, refine_cond) }?;
            // the flags of each batch row while its outputs are still in cache (and the pool's
            // threads awake): no second call from Python
            let flags = match flag_limits {
                Some((cond_max, min_rel_amplitude, max_rel_std, dof)) => {
                    let mut code = vec![0u8; npts];
                    let mut rel_amp = out_buf(npts);
                    let mut ok = vec![false; npts];
                    let row = n.max(1);
                    for (b, ((oc, ra), okb)) in code.chunks_mut(row).zip(rel_amp.chunks_mut(row)).zip(ok.chunks_mut(row)).enumerate() {
                        let rows = b * n..(b + 1) * n;
                        let rs = if want_std { &rel[rows.clone()] } else { &[][..] };
                        let cst = if want_std { &cs[8 * rows.start..8 * rows.end] } else { &[][..] };
                        identify::flag_codes(&cond[2 * rows.start..2 * rows.end], &amp[rows.clone()], rs, &c[8 * rows.start..8 * rows.end], cst, &[dof], cond_max, min_rel_amplitude, max_rel_std, ra, oc, okb)?;
                    }
                    Some((code, rel_amp, ok))
                }
                None => None,
            };
            Ok::<_, CoreError>((k, c, cond, resid, amp, ks, cs, rel, flags, nbad))
        })
    })?
    .map_err(core_err)?;
    let (k, c, cond, resid, amp, ks, cs, rel, flags, nbad) = res;
    let sh = [batch, n, 2, 2, 2];
    let kst = if want_std { Some(to_py(py, ks, &sh)?) } else { None };
    let cst = if want_std { Some(to_py(py, cs, &sh)?) } else { None };
    let relp = if want_std { Some(to_py(py, rel, &[batch, n])?) } else { None };
    let (code, rel_amp, ok) = match flags {
        Some((code, rel_amp, ok)) => {
            (Some(to_py(py, code, &[batch, n])?), Some(to_py(py, rel_amp, &[batch, n])?), Some(to_py(py, ok, &[batch, n])?))
        }
        None => (None, None, None),
    };
    Ok((to_py(py, k, &sh)?, to_py(py, c, &sh)?, to_py(py, cond, &[batch, n, 2])?, to_py(py, resid, &[batch, n])?, to_py(py, amp, &[batch, n])?, kst, cst, relp, code, rel_amp, ok, nbad))
}

/// A run's covariance moved between planes with its responses (see
/// rotorid_core::covariance::move_covariances): `a`, `b` the (8, 8) real maps of [Re q, Im q]
/// (`b` with pedestal motion: q' = A q + B p), `cov` (n, 8, 8), `pedestal_cov` and `cross` (n, 8,
/// 8) with `b` (cross None: uncorrelated). Returns (cov', cross' or None).
#[pyfunction]
#[pyo3(signature = (a, b, cov, pedestal_cov=None, cross=None))]
#[allow(clippy::type_complexity)]
fn move_covariances<'py>(
    py: Python<'py>,
    a: PyReadonlyArrayDyn<'py, f64>,
    b: Option<PyReadonlyArrayDyn<'py, f64>>,
    cov: PyReadonlyArrayDyn<'py, f64>,
    pedestal_cov: Option<PyReadonlyArrayDyn<'py, f64>>,
    cross: Option<PyReadonlyArrayDyn<'py, f64>>,
) -> PyResult<(Bound<'py, PyArrayDyn<f64>>, Option<Bound<'py, PyArrayDyn<f64>>>)> {
    let map = |m: &PyReadonlyArrayDyn<'py, f64>, name: &str| -> PyResult<[f64; 64]> {
        check_shape(name, m.shape(), &[8, 8])?;
        Ok(slice(m, name)?.try_into().unwrap())
    };
    let am = map(&a, "a")?;
    let bm = b.as_ref().map(|b| map(b, "b")).transpose()?;
    let n = cov.shape().first().copied().unwrap_or(0);
    check_shape("cov", cov.shape(), &[n, 8, 8])?;
    if bm.is_some() != pedestal_cov.is_some() {
        return Err(PyValueError::new_err("pedestal_cov is given with the pedestal map b, and only then"));
    }
    if cross.is_some() && bm.is_none() {
        return Err(PyValueError::new_err("cross is given with the pedestal map b only"));
    }
    for (name, x) in [("pedestal_cov", &pedestal_cov), ("cross", &cross)] {
        if let Some(x) = x {
            check_shape(name, x.shape(), &[n, 8, 8])?;
        }
    }
    let rc = rotorid_core::covariance::RunCov {
        q: slice(&cov, "cov")?,
        ped: match &pedestal_cov {
            Some(p) => slice(p, "pedestal_cov")?,
            None => &[],
        },
        cross: match &cross {
            Some(x) => slice(x, "cross")?,
            None => &[],
        },
    };
    check_alloc("move_covariances", n.checked_mul(128), 8)?;
    let (c, x) = py
        .detach(|| {
            guarded(|| {
                let mut c = out_buf(n * 64);
                let mut x = if bm.is_some() { out_buf(n * 64) } else { Vec::new() };
                rotorid_core::covariance::move_covariances(&am, bm.as_ref(), rc, &mut c, bm.is_some().then_some(&mut x[..])).map(|_| (c, x))
            })
        })?
        .map_err(core_err)?;
    let x = if bm.is_some() { Some(to_py(py, x, &[n, 8, 8])?) } else { None };
    Ok((to_py(py, c, &[n, 8, 8])?, x))
}

/// Check measurement covariances and stack them (see rotorid_core::covariance): `covs` a list of
/// R float64 arrays (n, m, m). Returns (the stacked copy (R, n, m, m), every entry of an unknown
/// matrix NaN; None or the first fault as (kind, array, point), kind "inf", "asymmetric" or
/// "indefinite").
#[pyfunction]
#[allow(clippy::type_complexity)]
fn check_covariances<'py>(
    py: Python<'py>,
    covs: &Bound<'py, PyList>,
    m: usize,
) -> PyResult<(Bound<'py, PyArrayDyn<f64>>, Option<(&'static str, usize, usize)>)> {
    use rotorid_core::covariance::{self, CovFault};
    let arrays: Vec<PyReadonlyArrayDyn<'py, f64>> = list_arrays(covs, "covs", "float64")?;
    let n = arrays.first().map(|a| a.shape().first().copied().unwrap_or(0)).unwrap_or(0);
    for (r, a) in arrays.iter().enumerate() {
        check_shape(&format!("covs[{r}]"), a.shape(), &[n, m, m])?;
    }
    let each = n * m * m;
    check_alloc("check_covariances", each.checked_mul(arrays.len()), 8)?;
    let slices = list_slices(&arrays, "covs")?;
    let (out, fault) = py
        .detach(|| {
            guarded(|| {
                let mut out = out_buf(each * slices.len());
                for (r, (src, dst)) in slices.iter().zip(out.chunks_mut(each.max(1))).enumerate() {
                    if let Some(f) = covariance::check_covariances(src, m, dst)? {
                        return Ok((out, Some((r, f))));
                    }
                }
                Ok::<_, CoreError>((out, None))
            })
        })?
        .map_err(core_err)?;
    let fault = fault.map(|(r, f)| match f {
        CovFault::Infinite(p) => ("inf", r, p),
        CovFault::Asymmetric(p) => ("asymmetric", r, p),
        CovFault::Indefinite(p) => ("indefinite", r, p),
    });
    Ok((to_py(py, out, &[arrays.len(), n, m, m])?, fault))
}

/// Points whose covariance is unknown (see rotorid_core::covariance::unknown_points): `blocks` a
/// list of float64 arrays with n points each (first axis). Returns (n,) bool.
#[pyfunction]
fn unknown_points<'py>(py: Python<'py>, blocks: &Bound<'py, PyList>, n: usize) -> PyResult<Bound<'py, PyArrayDyn<bool>>> {
    let arrays: Vec<PyReadonlyArrayDyn<'py, f64>> = list_arrays(blocks, "blocks", "float64")?;
    for (r, a) in arrays.iter().enumerate() {
        if a.shape().first() != Some(&n) {
            return Err(PyValueError::new_err(format!("blocks[{r}] has shape {:?}, expected ({n}, ...)", a.shape())));
        }
    }
    let slices = list_slices(&arrays, "blocks")?;
    check_alloc("unknown_points", Some(n), 1)?;
    let out = py
        .detach(|| {
            guarded(|| {
                let mut out = vec![false; n];
                rotorid_core::covariance::unknown_points(&slices, &mut out).map(|_| out)
            })
        })?
        .map_err(core_err)?;
    to_py(py, out, &[n])
}

/// A run's covariance blocks as Python gives them: (cov, pedestal_cov, cross or None), (n, 8, 8) each.
type CovBlocks<'py> = (PyReadonlyArrayDyn<'py, f64>, PyReadonlyArrayDyn<'py, f64>, Option<PyReadonlyArrayDyn<'py, f64>>);

/// `covs`: a list of one (cov, pedestal_cov, cross or None) per run.
fn cov_blocks<'py>(covs: &Bound<'py, PyAny>, runs: usize) -> PyResult<Vec<CovBlocks<'py>>> {
    let out: Vec<CovBlocks<'py>> = covs
        .cast::<PyList>()
        .map_err(|_| PyTypeError::new_err("covs must be a list of (cov, pedestal_cov, cross or None), one per run"))?
        .iter()
        .enumerate()
        .map(|(r, a)| a.extract().map_err(|_| PyTypeError::new_err(format!("covs[{r}] must be (cov, pedestal_cov, cross or None) of float64 arrays"))))
        .collect::<PyResult<_>>()?;
    if out.len() != runs {
        return Err(PyValueError::new_err(format!("covs has {} entries, expected one per run ({runs})", out.len())));
    }
    Ok(out)
}

/// The blocks of [`cov_blocks`] as the core takes them, each checked to be (n, 8, 8).
fn cov_block_slices<'a>(arrays: &'a [CovBlocks<'_>], n: usize) -> PyResult<Vec<rotorid_core::covariance::RunCov<'a>>> {
    let mut out = Vec::with_capacity(arrays.len());
    for (r, (cq, cp, cx)) in arrays.iter().enumerate() {
        check_shape(&format!("covs[{r}][0]"), cq.shape(), &[n, 8, 8])?;
        check_shape(&format!("covs[{r}][1]"), cp.shape(), &[n, 8, 8])?;
        if let Some(x) = cx {
            check_shape(&format!("covs[{r}][2]"), x.shape(), &[n, 8, 8])?;
        }
        out.push(rotorid_core::covariance::RunCov {
            q: slice(cq, &format!("covs[{r}][0]"))?,
            ped: slice(cp, &format!("covs[{r}][1]"))?,
            cross: match cx {
                Some(x) => slice(x, &format!("covs[{r}][2]"))?,
                None => &[],
            },
        });
    }
    Ok(out)
}

/// Measurement covariance propagated through the identification (see
/// identify::propagate): arguments as `identify` for one problem (`q` and `q_ped` lists of R
/// arrays (n, 4) at the bearings), with `covs` (R, n, m, m) the runs' covariances of [Re q, Im q]
/// (m = 8) or, with `q_ped`, of [Re q, Im q, Re q_ped, Im q_ped] (m = 16), or then a list of one
/// (cov, pedestal_cov, cross or None) of (n, 8, 8) blocks per run; NaN where unknown;
/// `shared` (n, m, m) a covariance common to every pair of runs, or None. `calibration`: the
/// accelerometers' calibration uncertainty (gain_std, phase_std_rad, probe_maps (R, 4, 4): each
/// run's map from measured pedestal motion to relative motion at the bearings, zeros for a run
/// measured there), with `q_ped`; then `covs` may be None (the calibration's covariance alone).
/// Returns (cov (n, 16, 16), bias (n, 16) or None, unknown (n,) uint8, k_std (n, 2, 2, 2), c_std
/// (n, 2, 2, 2), meas_k_std, meas_c_std), cov and bias in eq. 9 order, the standard errors in the
/// identification's [bearing, i, j] order; the last two (those of the measurement covariance
/// alone) with `meas_std` and a calibration, else None.
#[pyfunction]
#[pyo3(signature = (rotor, w, spin, q, e, gain, covs, identical=false, method="forces", sigma=None, q_ped=None, w_scale=None, shared=None, bias=true, calibration=None, meas_std=false))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn propagate<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    spin: Option<PyReadonlyArrayDyn<'py, f64>>,
    q: &Bound<'py, PyAny>,
    e: PyReadonlyArrayDyn<'py, C64>,
    gain: Option<PyReadonlyArrayDyn<'py, f64>>,
    covs: Option<&Bound<'py, PyAny>>,
    identical: bool,
    method: &str,
    sigma: Option<PyReadonlyArrayDyn<'py, f64>>,
    q_ped: Option<&Bound<'py, PyAny>>,
    w_scale: Option<f64>,
    shared: Option<PyReadonlyArrayDyn<'py, f64>>,
    bias: bool,
    calibration: Option<(f64, f64, PyReadonlyArrayDyn<'py, f64>)>,
    meas_std: bool,
) -> PyResult<PropagateOut<'py>> {
    let rot = rotor_of(&rotor)?;
    let resp = responses(q)?;
    if resp.batch != 1 {
        return Err(PyValueError::new_err(format!("q: the propagation takes one problem, got a batch of {}", resp.batch)));
    }
    let (runs, n) = (resp.runs, resp.n);
    let axes = AxisValues::new(&w, &sigma, n, w_scale)?;
    let report = report_method(method)?;
    let blocks = resp.blocks()?;
    let ped = pedestal_responses(q_ped, &resp)?;
    let ped_blocks = pedestal_blocks(&ped)?;
    let m = if ped.is_some() { 16 } else { 8 };
    let covs = covs.filter(|c| !c.is_none());
    let dense: Option<PyReadonlyArrayDyn<'py, f64>> = match covs {
        Some(c) if !c.is_instance_of::<PyList>() => {
            let a: PyReadonlyArrayDyn<'py, f64> = c.extract().map_err(|_| PyTypeError::new_err("covs must be a float64 array (R, n, m, m) or a list of blocks"))?;
            check_shape("covs", a.shape(), &[runs, n, m, m])?;
            Some(a)
        }
        _ => None,
    };
    let block_arrays = match covs {
        Some(c) if c.is_instance_of::<PyList>() => {
            if m != 16 {
                return Err(PyValueError::new_err("covs: blocks (cov, pedestal_cov, cross) are for runs with pedestal motion (q_ped)"));
            }
            cov_blocks(c, runs)?
        }
        _ => Vec::new(),
    };
    let block_slices = cov_block_slices(&block_arrays, n)?;
    if covs.is_none() && calibration.is_none() {
        return Err(PyValueError::new_err("covs: None needs a calibration"));
    }
    if let Some(sh) = &shared {
        check_shape("shared", sh.shape(), &[n, m, m])?;
    }
    let maps: Vec<[f64; 16]> = match &calibration {
        Some((_, _, mp)) => {
            check_shape("calibration probe_maps", mp.shape(), &[runs, 4, 4])?;
            slice(mp, "calibration probe_maps")?.chunks(16).map(|c| c.try_into().unwrap()).collect()
        }
        None => Vec::new(),
    };
    let ident = ident_problem(rot, &resp, &axes, spin.as_ref(), &e, &gain, &blocks, &ped_blocks, None, identical)?;
    let prob = identify::propagate::CovProblem {
        ident,
        report,
        covs: match (&dense, covs) {
            (Some(a), _) => identify::propagate::RunCovs::Dense(slice(a, "covs")?),
            (None, Some(_)) => identify::propagate::RunCovs::Blocks(&block_slices),
            (None, None) => identify::propagate::RunCovs::Absent,
        },
        shared: match &shared {
            Some(sh) => slice(sh, "shared")?,
            None => &[],
        },
        calibration: calibration.as_ref().map(|&(gain_std, phase_std, _)| identify::propagate::Calibration { gain_std, phase_std, probe_maps: &maps }),
    };
    let meas_std = meas_std && calibration.is_some();
    check_alloc("propagate", n.checked_mul(289 + if meas_std { 16 } else { 0 }), 8)?;
    let (cov, b, unknown, ks, cs, mk, mc) = py
        .detach(|| {
            guarded(|| {
                let mut cov = out_buf(n * 256);
                let mut b = if bias { out_buf(n * 16) } else { Vec::new() };
                let mut unknown = vec![0u8; n];
                let (mut ks, mut cs) = (out_buf(n * 8), out_buf(n * 8));
                let (mut mk, mut mc) = if meas_std { (out_buf(n * 8), out_buf(n * 8)) } else { (Vec::new(), Vec::new()) };
                let out = identify::propagate::CovOut {
                    cov: &mut cov,
                    bias: if bias { Some(&mut b[..]) } else { None },
                    unknown: &mut unknown,
                    k_std: &mut ks,
                    c_std: &mut cs,
                    meas_std: if meas_std { Some([&mut mk[..], &mut mc[..]]) } else { None },
                };
                identify::propagate::propagate(&prob, out).map(|_| (cov, b, unknown, ks, cs, mk, mc))
            })
        })?
        .map_err(core_err)?;
    let bp = if bias { Some(to_py(py, b, &[n, 16])?) } else { None };
    let sh = [n, 2, 2, 2];
    let (mk, mc) = if meas_std { (Some(to_py(py, mk, &sh)?), Some(to_py(py, mc, &sh)?)) } else { (None, None) };
    Ok((to_py(py, cov, &[n, 16, 16])?, bp, to_py(py, unknown, &[n])?, to_py(py, ks, &sh)?, to_py(py, cs, &sh)?, mk, mc))
}

/// What `propagate` returns: (cov, bias, unknown, k_std, c_std, meas_k_std, meas_c_std).
type PropagateOut<'py> = (
    Bound<'py, PyArrayDyn<f64>>,
    Option<Bound<'py, PyArrayDyn<f64>>>,
    Bound<'py, PyArrayDyn<u8>>,
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
    Option<Bound<'py, PyArrayDyn<f64>>>,
    Option<Bound<'py, PyArrayDyn<f64>>>,
);

/// Largest standard error relative to the bearing's direct coefficients per point (see
/// identify::relative_std). k, c, k_std, c_std: (n, 8) -> (n,).
#[pyfunction]
fn relative_std<'py>(
    py: Python<'py>,
    k: PyReadonlyArrayDyn<'py, f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    k_std: PyReadonlyArrayDyn<'py, f64>,
    c_std: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let n = k.shape().first().copied().unwrap_or(0);
    for (name, a) in [("k", &k), ("c", &c), ("k_std", &k_std), ("c_std", &c_std)] {
        check_shape(name, a.shape(), &[n, 8])?;
    }
    let (ks, cs, kss, css) = (slice(&k, "k")?, slice(&c, "c")?, slice(&k_std, "k_std")?, slice(&c_std, "c_std")?);
    let out = py.detach(|| {
        guarded(|| {
            let mut out = out_buf(n);
            identify::relative_std(ks, cs, kss, css, &mut out).map(|_| out)
        })
    })?
    .map_err(core_err)?;
    to_py(py, out, &[n])
}

/// Flag codes of an identification in one pass (see identify::flag_codes): cond (n, 2), amp (n,),
/// rel_std (n,) or None (unknown), c and c_std (n, 2, 2, 2) or None (no damping test; unknown
/// errors), dof (1,), (n,) or (n, 2, 2, 2) the degrees of freedom of c_std or None (+inf) -> (code uint8 (n,),
/// amp / max amp (n,), ok = code == 0 (n,)).
#[pyfunction]
#[pyo3(signature = (cond, amp, rel_std, cond_max, min_rel_amplitude, max_rel_std, c=None, c_std=None, dof=None))]
#[allow(clippy::too_many_arguments)]
fn flag_codes<'py>(
    py: Python<'py>,
    cond: PyReadonlyArrayDyn<'py, f64>,
    amp: PyReadonlyArrayDyn<'py, f64>,
    rel_std: Option<PyReadonlyArrayDyn<'py, f64>>,
    cond_max: f64,
    min_rel_amplitude: f64,
    max_rel_std: f64,
    c: Option<PyReadonlyArrayDyn<'py, f64>>,
    c_std: Option<PyReadonlyArrayDyn<'py, f64>>,
    dof: Option<PyReadonlyArrayDyn<'py, f64>>,
) -> PyResult<(Bound<'py, PyArrayDyn<u8>>, Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<bool>>)> {
    let n = amp.len();
    if let Some(d) = &dof {
        if d.shape() != [1] && d.shape() != [n, 2, 2, 2] {
            check_shape("dof", d.shape(), &[n])?;
        }
    }
    let dofs: &[f64] = match &dof {
        Some(d) => slice(d, "dof")?,
        None => &[],
    };
    check_shape("cond", cond.shape(), &[n, 2])?;
    if let Some(r) = &rel_std {
        check_shape("rel_std", r.shape(), &[n])?;
    }
    for (name, a) in [("c", &c), ("c_std", &c_std)] {
        if let Some(a) = a {
            check_shape(name, a.shape(), &[n, 2, 2, 2])?;
        }
    }
    let rs: &[f64] = match &rel_std {
        Some(r) => slice(r, "rel_std")?,
        None => &[],
    };
    let cd: &[f64] = match &c {
        Some(a) => slice(a, "c")?,
        None => &[],
    };
    let cds: &[f64] = match &c_std {
        Some(a) => slice(a, "c_std")?,
        None => &[],
    };
    let (cs, am) = (slice(&cond, "cond")?, slice(&amp, "amp")?);
    let (code, rel, ok) = py.detach(|| {
        guarded(|| {
            let mut code = vec![0u8; n];
            let mut rel = out_buf(n);
            let mut ok = vec![false; n];
            identify::flag_codes(cs, am, rs, cd, cds, dofs, cond_max, min_rel_amplitude, max_rel_std, &mut rel, &mut code, &mut ok).map(|_| (code, rel, ok))
        })
    })?
    .map_err(core_err)?;
    Ok((to_py(py, code, &[n])?, to_py(py, rel, &[n])?, to_py(py, ok, &[n])?))
}

/// The arguments of a modal analysis: k, c (n, 8), spin (n,) as slices, with the output memory
/// (`per_point` complex values per speed) checked.
fn modal_args<'a>(
    what: &str,
    n: usize,
    k: &'a PyReadonlyArrayDyn<'_, f64>,
    c: &'a PyReadonlyArrayDyn<'_, f64>,
    spin: &'a PyReadonlyArrayDyn<'_, f64>,
    per_point: usize,
) -> PyResult<(&'a [f64], &'a [f64], &'a [f64])> {
    check_shape("k", k.shape(), &[n, 8])?;
    check_shape("c", c.shape(), &[n, 8])?;
    check_alloc(what, n.checked_mul(per_point), 16)?;
    Ok((slice(k, "k")?, slice(c, "c")?, slice(spin, "spin")?))
}

/// Batched eigen-analysis (see modal.rs). Returns (lam (n, 4), shapes (n, 4, 4), n_failed).
#[pyfunction]
#[pyo3(name = "modal")]
fn py_modal<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    k: PyReadonlyArrayDyn<'py, f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    spin: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<(Bound<'py, PyArrayDyn<C64>>, Bound<'py, PyArrayDyn<C64>>, usize)> {
    let rot = rotor_of(&rotor)?;
    let n = spin.len();
    let (ks, cs, ss) = modal_args("modal", n, &k, &c, &spin, 20)?;
    let (lam, sh, nf) = py.detach(|| {
        guarded(|| {
            let mut lam = vec![C64::new(0.0, 0.0); n * 4];
            let mut sh = vec![C64::new(0.0, 0.0); n * 16];
            modal::modal(&rot, ks, cs, ss, &mut lam, &mut sh).map(|nf| (lam, sh, nf))
        })
    })?
    .map_err(core_err)?;
    Ok((to_py(py, lam, &[n, 4])?, to_py(py, sh, &[n, 4, 4])?, nf))
}

fn pedestals_of(p: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<pedestal::Pedestals> {
    pedestal::Pedestals::from_slice(slice(p, "pedestals")?).map_err(core_err)
}

/// Forced response with flexible pedestals (see pedestal.rs): (q (n, nrhs, 4), q_ped (n, nrhs,
/// 4), n_singular). `gain` (n,) scales each point's solution; `imbalance=True` scales it by
/// spin^2 instead (no gain array; not with `gain`). `relative=True`: q is the rotor's motion
/// relative to the pedestals (q_abs - q_ped, formed in the core), else its absolute motion;
/// with `planes` (2, 2), the bearings-to-probes transform T, the relative reading at the probe
/// planes T q_abs - q_ped (needs `relative=True`). `spin` and `w_scale` as in `forced_response`.
#[pyfunction]
#[pyo3(signature = (rotor, k, c, pedestals, spin, w, force, gain=None, imbalance=false, relative=false, w_scale=None, planes=None))]
#[allow(clippy::too_many_arguments)]
fn forced_response_pedestal<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    k: PyReadonlyArrayDyn<'py, f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    pedestals: PyReadonlyArrayDyn<'py, f64>,
    spin: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    force: PyReadonlyArrayDyn<'py, C64>,
    gain: Option<PyReadonlyArrayDyn<'py, f64>>,
    imbalance: bool,
    relative: bool,
    w_scale: Option<f64>,
    planes: Option<PyReadonlyArrayDyn<'py, f64>>,
) -> PyResult<(Bound<'py, PyArrayDyn<C64>>, Bound<'py, PyArrayDyn<C64>>, usize)> {
    let rot = rotor_of(&rotor)?;
    let ped = pedestals_of(&pedestals)?;
    let planes = planes.as_ref().map(|t| plane_transform("planes", t)).transpose()?;
    let n = w.len();
    let (ss, ws) = (axis_values("spin", &spin, n, None)?, axis_values("w", &w, n, w_scale)?);
    // q_abs and q_ped (4 + 4 per point) and the core's k_eff, c_eff, transfer (about 2 more)
    let nrhs = forced_shapes("forced_response_pedestal", n, &k, &c, None, &force, gain.as_ref(), 10)?;
    let (ks, cs, fsl) = (slice(&k, "k")?, slice(&c, "c")?, slice(&force, "force")?);
    let (ss, ws) = (&ss[..], &ws[..]);
    let g = match (&gain, imbalance) {
        (Some(_), true) => return Err(PyValueError::new_err("gain and imbalance=True exclude each other")),
        (Some(g), false) => forced::Gain::PerPoint(slice(g, "gain")?),
        (None, true) => forced::Gain::SpinSquared,
        (None, false) => forced::Gain::One,
    };
    let motion = match (relative, planes) {
        (false, None) => pedestal::RotorMotion::Absolute,
        (true, None) => pedestal::RotorMotion::Relative,
        (true, Some(t)) => pedestal::RotorMotion::RelativeAtPlanes(t),
        (false, Some(_)) => return Err(PyValueError::new_err("planes needs relative=True (the reading of probes riding on the pedestals)")),
    };
    let (qa, qp, nsing) = py
        .detach(|| {
            guarded(|| {
                let mut qa = out_buf(n * nrhs * 4);
                let mut qp = out_buf(n * nrhs * 4);
                pedestal::forced_response(&rot, ks, cs, &ped, ss, ws, fsl, nrhs, g, motion, &mut qa, &mut qp).map(|ns| (qa, qp, ns))
            })
        })?
        .map_err(core_err)?;
    Ok((to_py(py, qa, &[n, nrhs, 4])?, to_py(py, qp, &[n, nrhs, 4])?, nsing))
}

/// Effective (series) bearing + pedestal coefficients (see pedestal.rs). k, c: (n or 1, 8);
/// w: (n,). Returns (k_eff (n, 8), c_eff (n, 8), transfer (n, 8) complex, n_singular).
#[pyfunction]
fn effective_coefficients<'py>(
    py: Python<'py>,
    k: PyReadonlyArrayDyn<'py, f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    pedestals: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<(Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<C64>>, usize)> {
    let ped = pedestals_of(&pedestals)?;
    let n = w.len();
    check_alloc("effective_coefficients", n.checked_mul(32), 8)?;
    let (ks, cs, ws) = (slice(&k, "k")?, slice(&c, "c")?, slice(&w, "w")?);
    let (ke, ce, tr, nb) = py
        .detach(|| {
            guarded(|| {
                let mut ke = vec![0.0; n * 8];
                let mut ce = vec![0.0; n * 8];
                let mut tr = vec![C64::new(0.0, 0.0); n * 8];
                pedestal::effective_coefficients(ks, cs, &ped, ws, &mut ke, &mut ce, &mut tr).map(|nb| (ke, ce, tr, nb))
            })
        })?
        .map_err(core_err)?;
    Ok((to_py(py, ke, &[n, 8])?, to_py(py, ce, &[n, 8])?, to_py(py, tr, &[n, 8])?, nb))
}

/// Modal analysis of the rotor on flexible pedestals (see pedestal.rs). Returns
/// (lam (n, 8), shapes (n, 8, 8), n_failed).
#[pyfunction]
fn modal_pedestal<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    k: PyReadonlyArrayDyn<'py, f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    pedestals: PyReadonlyArrayDyn<'py, f64>,
    spin: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<(Bound<'py, PyArrayDyn<C64>>, Bound<'py, PyArrayDyn<C64>>, usize)> {
    let rot = rotor_of(&rotor)?;
    let ped = pedestals_of(&pedestals)?;
    let n = spin.len();
    let (ks, cs, ss) = modal_args("modal_pedestal", n, &k, &c, &spin, 72)?;
    let (lam, sh, nf) = py
        .detach(|| {
            guarded(|| {
                let mut lam = vec![C64::new(0.0, 0.0); n * 8];
                let mut sh = vec![C64::new(0.0, 0.0); n * 64];
                pedestal::modal(&rot, ks, cs, &ped, ss, &mut lam, &mut sh).map(|nf| (lam, sh, nf))
            })
        })?
        .map_err(core_err)?;
    Ok((to_py(py, lam, &[n, 8])?, to_py(py, sh, &[n, 8, 8])?, nf))
}

/// Bearing film in series with a damper through the damper journal's mass (see series.rs):
/// z_bearing, z_damper (n or 1, 2, 2) complex, journal_mass (n or 1,), w (n,) rad/s, or any axis
/// times `w_scale` in rad/s (2 pi for one in Hz: formed point by point, no (n,) array). Returns
/// (z_eq (n, 2, 2), n_singular).
#[pyfunction]
#[pyo3(signature = (z_bearing, z_damper, journal_mass, w, w_scale=1.0))]
fn series_impedance<'py>(
    py: Python<'py>,
    z_bearing: PyReadonlyArrayDyn<'py, C64>,
    z_damper: PyReadonlyArrayDyn<'py, C64>,
    journal_mass: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    w_scale: f64,
) -> PyResult<(Bound<'py, PyArrayDyn<C64>>, usize)> {
    let n = w.len();
    for (name, a) in [("z_bearing", &z_bearing), ("z_damper", &z_damper)] {
        let sh = a.shape();
        if sh.len() != 3 || sh[1] != 2 || sh[2] != 2 || !(sh[0] == n || sh[0] == 1) {
            return Err(PyValueError::new_err(format!("{name} has shape {sh:?}, expected ({n} or 1, 2, 2)")));
        }
    }
    let ms = journal_mass.shape();
    if ms.len() != 1 || !(ms[0] == n || ms[0] == 1) {
        return Err(PyValueError::new_err(format!("journal_mass has shape {ms:?}, expected ({n} or 1,)")));
    }
    check_alloc("series_impedance", n.checked_mul(4), 16)?;
    let (zb, zd, m, ws) =
        (slice(&z_bearing, "z_bearing")?, slice(&z_damper, "z_damper")?, slice(&journal_mass, "journal_mass")?, slice(&w, "w")?);
    let (out, nb) = py
        .detach(|| {
            guarded(|| {
                let mut out = vec![C64::new(0.0, 0.0); n * 4];
                series::series_impedance_scaled(zb, zd, m, ws, w_scale, &mut out).map(|nb| (out, nb))
            })
        })?
        .map_err(core_err)?;
    Ok((to_py(py, out, &[n, 2, 2])?, nb))
}

/// The arguments `identify` and `bearing_forces` share, their shapes checked (each named), as the
/// core's problem; it borrows the caller's blocks of q and q_ped.
#[allow(clippy::too_many_arguments)]
/// The w and sigma an identification reads: `w` times `w_scale` and a (1,) `sigma` repeated (see
/// [`axis_values`]).
struct AxisValues<'a> {
    w: Cow<'a, [f64]>,
    sigma: Cow<'a, [f64]>,
}

impl<'a> AxisValues<'a> {
    fn new(w: &'a PyReadonlyArrayDyn<'_, f64>, sigma: &'a Option<PyReadonlyArrayDyn<'_, f64>>, n: usize, w_scale: Option<f64>) -> PyResult<Self> {
        check_shape("w", w.shape(), &[n])?;
        Ok(AxisValues {
            w: axis_values("w", w, n, w_scale)?,
            sigma: match sigma {
                Some(sg) => axis_values("sigma", sg, n, None)?,
                None => Cow::Borrowed(&[]),
            },
        })
    }
}

#[allow(clippy::too_many_arguments)]
fn ident_problem<'a>(
    rotor: Rotor,
    resp: &Responses<'_>,
    axes: &'a AxisValues<'a>,
    spin: Option<&'a PyReadonlyArrayDyn<'_, f64>>,
    e: &'a PyReadonlyArrayDyn<'_, C64>,
    gain: &'a Option<PyReadonlyArrayDyn<'_, f64>>,
    q: &'a [&'a [C64]],
    q_ped: &'a [&'a [C64]],
    planes: Option<&PyReadonlyArrayDyn<'_, f64>>,
    identical: bool,
) -> PyResult<identify::IdentProblem<'a>> {
    let (batch, runs, n) = (resp.batch, resp.runs, resp.n);
    if runs == 0 {
        return Err(PyValueError::new_err("at least one run is needed"));
    }
    for (name, a) in [("spin", spin), ("gain", gain.as_ref())] {
        let Some(a) = a else { continue };
        if a.shape() != [n] && a.shape() != [1] {
            return Err(PyValueError::new_err(format!("{name} has shape {:?}, expected ({n},) or (1,)", a.shape())));
        }
    }
    let es = e.shape().to_vec();
    if es.len() != 3 || es[1] != runs || es[2] != 4 || !(es[0] == 1 || es[0] == batch) {
        return Err(PyValueError::new_err(format!("e has shape {es:?}, expected (1 or {batch}, {runs}, 4)")));
    }
    let prob = identify::IdentProblem {
        rotor,
        w: &axes.w,
        // None: synchronous runs, whose spin speed is the vibration frequency
        spin: match spin {
            Some(s) => slice(s, "spin")?,
            None => &axes.w,
        },
        q,
        e: slice(e, "e")?,
        gain: match gain {
            Some(g) => slice(g, "gain")?,
            None => &[],
        },
        sigma: &axes.sigma,
        q_ped,
        planes: planes.map(|t| plane_transform("planes", t)).transpose()?,
        batch,
        runs,
        identical,
    };
    prob.check().map_err(core_err)?;
    Ok(prob)
}

/// Bearing reaction forces from the rotor equations (see identify::bearing_forces): arguments as
/// `identify`. Returns (B, R, n, 4) [f1x, f2x, f1y, f2y].
#[pyfunction]
#[pyo3(signature = (rotor, w, spin, q, e, gain, sigma=None, q_ped=None, planes=None))]
#[allow(clippy::too_many_arguments)]
fn bearing_forces<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    spin: PyReadonlyArrayDyn<'py, f64>,
    q: &Bound<'py, PyAny>,
    e: PyReadonlyArrayDyn<'py, C64>,
    gain: Option<PyReadonlyArrayDyn<'py, f64>>,
    sigma: Option<PyReadonlyArrayDyn<'py, f64>>,
    q_ped: Option<&Bound<'py, PyAny>>,
    planes: Option<PyReadonlyArrayDyn<'py, f64>>,
) -> PyResult<Bound<'py, PyArrayDyn<C64>>> {
    let rot = rotor_of(&rotor)?;
    ident_problem_of!(prob, resp; rot, q, q_ped, &w, &sigma, None, Some(&spin), &e, &gain, planes.as_ref(), false);
    let (batch, runs, n) = (resp.batch, resp.runs, resp.n);
    let total = batch.checked_mul(runs).and_then(|v| v.checked_mul(n)).and_then(|v| v.checked_mul(4));
    check_alloc("bearing_forces", total, 16)?;
    let total = total.unwrap_or(0);
    let out = py
        .detach(|| {
            guarded(|| {
                let mut out = vec![C64::new(0.0, 0.0); total];
                identify::bearing_forces(&prob, &mut out).map(|_| out)
            })
        })?
        .map_err(core_err)?;
    to_py(py, out, &[batch, runs, n, 4])
}

/// (k_std, c_std, dof) of `identical_std`.
type IdenticalStd<'py> = (Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<f64>>);

/// Residual-based standard errors of an identical-bearing identification with the structure of
/// its equation errors (see identify::identical): arguments as `identify` (identical=True), and
/// its estimate k, c (B, n, 2, 2, 2; bearing 1's half read). `noise_planes`: the (2, 2) eq. 19
/// transform from the probe planes, where the noise is white, for responses moved to the bearings
/// before the call (None: white where q is given). Returns k_std, c_std (B, n, 2, 2, 2) and the
/// real degrees of freedom of each row's errors (B, n, 2) [x row, y row]; NaN where the estimate
/// is not finite or the residual has no degree of freedom.
#[pyfunction]
#[pyo3(signature = (rotor, w, spin, q, e, gain, k, c, sigma=None, q_ped=None, planes=None, w_scale=None, noise_planes=None))]
#[allow(clippy::too_many_arguments)]
fn identical_std<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    spin: Option<PyReadonlyArrayDyn<'py, f64>>,
    q: &Bound<'py, PyAny>,
    e: PyReadonlyArrayDyn<'py, C64>,
    gain: Option<PyReadonlyArrayDyn<'py, f64>>,
    k: PyReadonlyArrayDyn<'py, f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    sigma: Option<PyReadonlyArrayDyn<'py, f64>>,
    q_ped: Option<&Bound<'py, PyAny>>,
    planes: Option<PyReadonlyArrayDyn<'py, f64>>,
    w_scale: Option<f64>,
    noise_planes: Option<PyReadonlyArrayDyn<'py, f64>>,
) -> PyResult<IdenticalStd<'py>> {
    let noise_t = noise_planes.map(|t| plane_transform("noise_planes", &t)).transpose()?;
    let rot = rotor_of(&rotor)?;
    ident_problem_of!(prob, resp; rot, q, q_ped, &w, &sigma, w_scale, spin.as_ref(), &e, &gain, planes.as_ref(), true);
    let (batch, n) = (resp.batch, resp.n);
    check_shape("k", k.shape(), &[batch, n, 2, 2, 2])?;
    check_shape("c", c.shape(), &[batch, n, 2, 2, 2])?;
    let (ks_in, cs_in) = (slice(&k, "k")?, slice(&c, "c")?);
    let npts = batch.checked_mul(n).ok_or_else(|| PyMemoryError::new_err("identical_std: batch x points overflows"))?;
    check_alloc("identical_std", npts.checked_mul(18), 8)?;
    let (ks, cs, dof) = py
        .detach(|| {
            guarded(|| {
                let (mut ks, mut cs, mut dof) = (vec![0.0; 8 * npts], vec![0.0; 8 * npts], vec![0.0; 2 * npts]);
                let out = identify::identical::IdenticalStdOut { k_std: &mut ks, c_std: &mut cs, dof: &mut dof };
                identify::identical::identical_std(&prob, ks_in, cs_in, noise_t, out).map(|_| (ks, cs, dof))
            })
        })?
        .map_err(core_err)?;
    Ok((to_py(py, ks, &[batch, n, 2, 2, 2])?, to_py(py, cs, &[batch, n, 2, 2, 2])?, to_py(py, dof, &[batch, n, 2])?))
}

/// The covariance fit's (theta (4, u), cov (4, u, u), resid (4,)).
type CovFitArrays<'py> = (Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<f64>>);

/// Pedestal identification (see pedestal_fit::fit): the bearing forces' arguments as
/// `bearing_forces` (one batch member; `q` and `q_ped` lists of runs or (1, R, n, 4) arrays),
/// `select` (n,) bool or None for every point, `cross` for the cross-coupled terms; `w_scale`: w is
/// `w_scale` times the given axis; `spin` None: spin = w (synchronous runs). Returns
/// (theta (4, u), cov (4, u, u), rank (4,) int, resid (4,), rows, cov_fit) with fits in the order
/// (pedestal, direction) = (1, x), (1, y), (2, x), (2, y); theta and cov NaN where rank < u.
/// With `covs` (per run (cov, pedestal_cov, cross or None), (n, 8, 8) each: the blocks of the
/// covariance of [Re q, Im q, Re q_ped, Im q_ped], known at the selected points) and optionally
/// `shared` (n, 16, 16): `cov_fit` = (theta, cov,
/// resid) of the weighted fit (`weighted`) or, unweighted, the sandwich covariance at the
/// unweighted theta (see pedestal_cov::cov_fit); None without `covs` or when a fit is rank
/// deficient.
#[pyfunction]
#[pyo3(signature = (rotor, w, spin, q, e, gain, q_ped, sigma=None, select=None, cross=false, w_scale=None, covs=None, shared=None, weighted=true))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn pedestal_fit<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    spin: Option<PyReadonlyArrayDyn<'py, f64>>,
    q: &Bound<'py, PyAny>,
    e: PyReadonlyArrayDyn<'py, C64>,
    gain: Option<PyReadonlyArrayDyn<'py, f64>>,
    q_ped: &Bound<'py, PyAny>,
    sigma: Option<PyReadonlyArrayDyn<'py, f64>>,
    select: Option<&Bound<'py, PyAny>>,
    cross: bool,
    w_scale: Option<f64>,
    covs: Option<&Bound<'py, PyAny>>,
    shared: Option<PyReadonlyArrayDyn<'py, f64>>,
    weighted: bool,
) -> PyResult<(
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<i64>>,
    Bound<'py, PyArrayDyn<f64>>,
    usize,
    Option<CovFitArrays<'py>>,
)> {
    let rot = rotor_of(&rotor)?;
    let resp = responses(q)?;
    let n = resp.n;
    let axes = AxisValues::new(&w, &sigma, n, w_scale)?;
    let blocks = resp.blocks()?;
    let ped = pedestal_responses(Some(q_ped), &resp)?.ok_or_else(|| PyValueError::new_err("q_ped is needed"))?;
    let ped_blocks = ped.blocks()?;
    let forces = ident_problem(rot, &resp, &axes, spin.as_ref(), &e, &gain, &blocks, &ped_blocks, None, false)?;
    let select: Option<PyReadonlyArrayDyn<'py, bool>> = match select {
        Some(s) if !s.is_none() => Some(s.extract().map_err(|_| PyTypeError::new_err(format!("select must be a bool array of shape ({n},)")))?),
        _ => None,
    };
    let select: &[bool] = match &select {
        Some(s) => {
            check_shape("select", s.shape(), &[n])?;
            slice(s, "select")?
        }
        None => &[],
    };
    // the runs' covariances as (q, pedestal, cross or None) blocks of (n, 8, 8), and the shared
    // (n, 16, 16) one, for the covariance fit
    let cov_arrays = match covs {
        Some(c) if !c.is_none() => cov_blocks(c, resp.runs)?,
        _ => Vec::new(),
    };
    let cov_slices = cov_block_slices(&cov_arrays, n)?;
    if let Some(sh) = &shared {
        check_shape("shared", sh.shape(), &[n, 16, 16])?;
    }
    let shared_slice: &[f64] = match &shared {
        Some(sh) => slice(sh, "shared")?,
        None => &[],
    };
    let problem = rotorid_core::pedestal_fit::PedestalFitProblem { forces, select, cross };
    let (fits, cfits) = py
        .detach(|| {
            guarded(|| {
                let fits = rotorid_core::pedestal_fit::fit(&problem)?;
                let u = if cross { 5 } else { 3 };
                // the covariance fit needs every unweighted fit of full rank (the caller names a
                // rank-deficient one)
                let cfits = if cov_slices.is_empty() || fits.iter().any(|f| f.rank < u) {
                    None
                } else {
                    let cp = pedestal_cov::CovFitProblem { fit: problem, covs: &cov_slices, shared: shared_slice };
                    let thetas: Vec<Vec<f64>> = fits.iter().map(|f| f.theta.clone()).collect();
                    Some(pedestal_cov::cov_fit(&cp, &thetas, weighted)?)
                };
                Ok::<_, CoreError>((fits, cfits))
            })
        })?
        .map_err(core_err)?;
    let u = if cross { 5 } else { 3 };
    let theta: Vec<f64> = fits.iter().flat_map(|f| f.theta.iter().copied()).collect();
    let cov: Vec<f64> = fits.iter().flat_map(|f| f.cov.iter().copied()).collect();
    let rank: Vec<i64> = fits.iter().map(|f| f.rank as i64).collect();
    let resid: Vec<f64> = fits.iter().map(|f| f.resid).collect();
    let cov_fit = match cfits {
        Some(cf) => {
            let th: Vec<f64> = cf.iter().flat_map(|f| f.theta.iter().copied()).collect();
            let cv: Vec<f64> = cf.iter().flat_map(|f| f.cov.iter().copied()).collect();
            let rs: Vec<f64> = cf.iter().map(|f| f.resid).collect();
            Some((to_py(py, th, &[4, u])?, to_py(py, cv, &[4, u, u])?, to_py(py, rs, &[4])?))
        }
        None => None,
    };
    Ok((to_py(py, theta, &[4, u])?, to_py(py, cov, &[4, u, u])?, to_py(py, rank, &[4])?, to_py(py, resid, &[4])?, fits[0].rows, cov_fit))
}

/// Sample times i dt of n samples (timesim::sample_times): (n,).
#[pyfunction]
fn sample_times<'py>(py: Python<'py>, n: usize, dt: f64) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    check_alloc("sample_times", Some(n), 8)?;
    let t = py.detach(|| {
        guarded(|| {
            let mut t = out_buf(n);
            timesim::sample_times(dt, &mut t);
            Ok::<_, CoreError>(t)
        })
    })?
    .map_err(core_err)?;
    to_py(py, t, &[n])
}

/// Time stepping of a discretized LTI system (see timesim.rs): phi (n, n), g0, g1 (n, m), u (N,
/// m), x0 (n,). Without `outputs`: ([states (N, n)], first non-finite step or None). With
/// `outputs`, a list of (c (p, n), d (p, m)): ([y_i (N, p_i) = c_i x + d_i u for each], first
/// non-finite step or None), no array of states.
#[pyfunction]
#[pyo3(signature = (phi, g0, g1, u, x0, outputs=None))]
#[allow(clippy::type_complexity)]
fn lti_run<'py>(
    py: Python<'py>,
    phi: PyReadonlyArrayDyn<'py, f64>,
    g0: PyReadonlyArrayDyn<'py, f64>,
    g1: PyReadonlyArrayDyn<'py, f64>,
    u: PyReadonlyArrayDyn<'py, f64>,
    x0: PyReadonlyArrayDyn<'py, f64>,
    outputs: Option<Vec<(PyReadonlyArrayDyn<'py, f64>, PyReadonlyArrayDyn<'py, f64>)>>,
) -> PyResult<(Vec<Bound<'py, PyArrayDyn<f64>>>, Option<usize>)> {
    let ps = phi.shape().to_vec();
    if ps.len() != 2 || ps[0] != ps[1] {
        return Err(PyValueError::new_err(format!("phi has shape {ps:?}, expected (n, n)")));
    }
    let n = ps[0];
    let us = u.shape().to_vec();
    if us.len() != 2 {
        return Err(PyValueError::new_err(format!("u has shape {us:?}, expected (N, m)")));
    }
    let (steps, m) = (us[0], us[1]);
    check_shape("g0", g0.shape(), &[n, m])?;
    check_shape("g1", g1.shape(), &[n, m])?;
    check_shape("x0", x0.shape(), &[n])?;
    let (p, a, b, uu, x) = (slice(&phi, "phi")?, slice(&g0, "g0")?, slice(&g1, "g1")?, slice(&u, "u")?, slice(&x0, "x0")?);
    let Some(outputs) = outputs else {
        check_alloc("lti_run", steps.checked_mul(n), 8)?;
        let (out, bad) = py
            .detach(|| {
                guarded(|| {
                    let mut out = out_buf(steps * n);
                    timesim::lti_run(n, m, p, a, b, uu, x, &mut out).map(|bad| (out, bad))
                })
            })?
            .map_err(core_err)?;
        return Ok((vec![to_py(py, out, &[steps, n])?], bad));
    };
    let mut eqs = Vec::with_capacity(outputs.len());
    let mut total = Some(0usize);
    for (c, d) in &outputs {
        let cs = c.shape().to_vec();
        if cs.len() != 2 || cs[1] != n {
            return Err(PyValueError::new_err(format!("an output's c has shape {cs:?}, expected (p, {n})")));
        }
        check_shape("an output's d", d.shape(), &[cs[0], m])?;
        total = total.and_then(|t| steps.checked_mul(cs[0]).and_then(|v| v.checked_add(t)));
        eqs.push((cs[0], slice(c, "c")?, slice(d, "d")?));
    }
    check_alloc("lti_run", total, 8)?;
    let (ys, bad) = py
        .detach(|| {
            guarded(|| {
                let mut ys: Vec<Vec<f64>> = eqs.iter().map(|&(pp, _, _)| out_buf(steps * pp)).collect();
                let mut outs: Vec<timesim::Output> =
                    eqs.iter().zip(ys.iter_mut()).map(|(&(pp, c, d), y)| timesim::Output { p: pp, c, d, out: y }).collect();
                let bad = timesim::lti_outputs(n, m, p, a, b, uu, x, &mut outs)?;
                drop(outs);
                Ok::<_, CoreError>((ys, bad))
            })
        })?
        .map_err(core_err)?;
    let arrays = ys.into_iter().zip(&eqs).map(|(y, &(pp, _, _))| to_py(py, y, &[steps, pp])).collect::<PyResult<Vec<_>>>()?;
    Ok((arrays, bad))
}

fn check_kp(kp: &[f64]) -> PyResult<()> {
    order::check_keyphasor(kp).map_err(core_err)
}

/// The channels of `x`: one (C, N) array, or a list of C arrays (N,) used where they are (no
/// (C, N) copy).
fn channel_arrays<'py>(x: &Bound<'py, PyAny>) -> PyResult<Vec<PyReadonlyArrayDyn<'py, f64>>> {
    if x.is_instance_of::<PyList>() {
        return x.extract();
    }
    let a: PyReadonlyArrayDyn<'py, f64> = x.extract()?;
    if a.shape().len() != 2 {
        return Err(PyValueError::new_err(format!("x has shape {:?}, expected (channels, samples)", a.shape())));
    }
    Ok(vec![a])
}

/// One slice per channel of the arrays [`channel_arrays`] returned for `x`.
fn channel_slices<'a>(x: &Bound<'_, PyAny>, arrays: &'a [PyReadonlyArrayDyn<'_, f64>]) -> PyResult<Vec<&'a [f64]>> {
    let mut channels: Vec<&[f64]> = Vec::new();
    for a in arrays {
        let sl = slice(a, "x")?;
        if x.is_instance_of::<PyList>() {
            if a.shape().len() != 1 {
                return Err(PyValueError::new_err(format!("a channel of x has shape {:?}, expected (samples,)", a.shape())));
            }
            channels.push(sl);
        } else {
            let (nch, n) = (a.shape()[0], a.shape()[1]);
            channels.extend((0..nch).map(|c| &sl[c * n..(c + 1) * n]));
        }
    }
    Ok(channels)
}

/// Index of the first value of the 1-D array `a` outside the open interval (lo, hi), NaN included,
/// or None (`bounds::first_outside`): one pass where NumPy's min and max take two.
#[pyfunction]
fn first_outside(py: Python<'_>, a: PyReadonlyArrayDyn<'_, f64>, lo: f64, hi: f64) -> PyResult<Option<usize>> {
    if a.shape().len() != 1 {
        return Err(PyValueError::new_err(format!("a has shape {:?}, expected (n,)", a.shape())));
    }
    match a.as_slice() {
        Ok(v) => Ok(py.detach(|| rotorid_core::bounds::first_outside(v, lo, hi))),
        // a strided view: its values in order
        Err(_) => Ok(a.as_array().iter().position(|&v| !(v > lo && v < hi))),
    }
}

/// Per-revolution order vectors of channels x (as for angle_resample) resampled at p uniform
/// angles per revolution for revolutions k0..k1, each revolution's drift ramp removed
/// (`order::order_vectors`). Returns complex (k1 - k0, len(orders), C), 0-pk.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn order_vectors<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    fs: f64,
    t0: f64,
    kp: PyReadonlyArrayDyn<'py, f64>,
    k0: usize,
    k1: usize,
    p: usize,
    orders: Vec<usize>,
) -> PyResult<Bound<'py, PyArrayDyn<C64>>> {
    let arrays = channel_arrays(x)?;
    let channels = channel_slices(x, &arrays)?;
    let kps = slice(&kp, "kp")?;
    let nch = channels.len();
    let revs = k1.saturating_sub(k0);
    check_alloc("order_vectors", nch.checked_mul(revs).and_then(|v| v.checked_mul(orders.len())), 16)?;
    let out = py.detach(|| {
        guarded(|| {
            let mut out = out_buf(revs * orders.len() * nch);
            order::order_vectors(&channels, fs, t0, kps, k0, k1, p, &orders, &mut out).map(|_| out)
        })
    })?
    .map_err(core_err)?;
    to_py(py, out, &[revs, orders.len(), nch])
}

/// Statistics of blocks of consecutive revolutions (rotorid_core::revolution_blocks): per_rev
/// (revs, orders, C) complex; rpm, t_mid (revs,); starts, lengths (blocks,) int64; cov_order: the
/// order index whose mean's covariance is estimated, or None, from at most max_batches batch
/// means. Returns (mean (blocks, orders, C),
/// cov (blocks, 2C, 2C), dof, rpm, t_mid (blocks,), scatter (blocks, 4)).
#[pyfunction]
#[pyo3(signature = (per_rev, rpm, t_mid, starts, lengths, cov_order=None, max_batches=revolution_blocks::MAX_BATCHES))]
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
fn block_statistics<'py>(
    py: Python<'py>,
    per_rev: PyReadonlyArrayDyn<'py, C64>,
    rpm: PyReadonlyArrayDyn<'py, f64>,
    t_mid: PyReadonlyArrayDyn<'py, f64>,
    starts: PyReadonlyArrayDyn<'py, i64>,
    lengths: PyReadonlyArrayDyn<'py, i64>,
    cov_order: Option<usize>,
    max_batches: usize,
) -> PyResult<(
    Bound<'py, PyArrayDyn<C64>>,
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
)> {
    let shape = per_rev.shape();
    if shape.len() != 3 {
        return Err(PyValueError::new_err(format!("per_rev has shape {shape:?}, expected (revolutions, orders, channels)")));
    }
    let (revs, no, nc) = (shape[0], shape[1], shape[2]);
    check_shape("rpm", rpm.shape(), &[revs])?;
    check_shape("t_mid", t_mid.shape(), &[revs])?;
    let nb = starts.len();
    check_shape("starts", starts.shape(), &[nb])?;
    check_shape("lengths", lengths.shape(), &[nb])?;
    let index = |name: &str, a: &PyReadonlyArrayDyn<'py, i64>| -> PyResult<Vec<usize>> {
        slice(a, name)?
            .iter()
            .map(|&v| usize::try_from(v).map_err(|_| PyValueError::new_err(format!("{name} must be >= 0, got {v}"))))
            .collect()
    };
    let (st, ln) = (index("starts", &starts)?, index("lengths", &lengths)?);
    let m = 2 * nc;
    check_alloc("block_statistics", nb.checked_mul(no * nc + m * m + 8), 16)?;
    let rev = revolution_blocks::Revolutions {
        per_rev: slice(&per_rev, "per_rev")?,
        orders: no,
        channels: nc,
        rpm: slice(&rpm, "rpm")?,
        t_mid: slice(&t_mid, "t_mid")?,
    };
    let (mean, cov, dof, sp, tm, scat) = py.detach(|| {
        guarded(|| {
            let (mut mean, mut cov, mut dof) = (out_buf(nb * no * nc), out_buf(nb * m * m), out_buf(nb));
            let (mut sp, mut tm, mut scat) = (out_buf(nb), out_buf(nb), out_buf(nb * 4));
            let mut out = revolution_blocks::BlockOutputs {
                mean: &mut mean,
                cov: &mut cov,
                dof: &mut dof,
                rpm: &mut sp,
                t_mid: &mut tm,
                scatter: &mut scat,
            };
            revolution_blocks::block_statistics(&rev, &st, &ln, cov_order, max_batches, &mut out).map(|_| (mean, cov, dof, sp, tm, scat))
        })
    })?
    .map_err(core_err)?;
    Ok((
        to_py(py, mean, &[nb, no, nc])?,
        to_py(py, cov, &[nb, m, m])?,
        to_py(py, dof, &[nb])?,
        to_py(py, sp, &[nb])?,
        to_py(py, tm, &[nb])?,
        to_py(py, scat, &[nb, 4])?,
    ))
}

/// Resample channels x (C, N), or a list of C channels (N,) used where they are, at p uniform
/// angles per revolution for revolutions k0..k1.
/// Returns (C, k1 - k0, p).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn angle_resample<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    fs: f64,
    t0: f64,
    kp: PyReadonlyArrayDyn<'py, f64>,
    k0: usize,
    k1: usize,
    p: usize,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let arrays = channel_arrays(x)?;
    let channels = channel_slices(x, &arrays)?;
    let kps = slice(&kp, "kp")?;
    check_kp(kps)?;
    if !(k0 < k1 && k1 < kps.len()) || p < 4 || !(fs > 0.0) {
        return Err(PyValueError::new_err(format!("need k0 < k1 < len(kp) = {}, p >= 4 and fs > 0 (got k0={k0}, k1={k1}, p={p}, fs={fs})", kps.len())));
    }
    let nch = channels.len();
    check_alloc("angle_resample", nch.checked_mul(k1 - k0).and_then(|v| v.checked_mul(p)), 8)?;
    let out = py.detach(|| {
        guarded(|| {
            let mut out = out_buf(nch * (k1 - k0) * p);
            order::angle_resample_channels(&channels, fs, t0, kps, k0, k1, p, &mut out).map(|_| out)
        })
    })?
    .map_err(core_err)?;
    to_py(py, out, &[nch, k1 - k0, p])
}

/// Time-domain run-out filter: x (C, N) minus the revolution signature template (C, p) placed by
/// the keyphasor times kp, for samples i0..i1. Returns ((C, i1 - i0), the number of NaN/inf input
/// samples in i0..i1); NaN outside the pulses.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn runout_subtract<'py>(
    py: Python<'py>,
    x: PyReadonlyArrayDyn<'py, f64>,
    fs: f64,
    t0: f64,
    kp: PyReadonlyArrayDyn<'py, f64>,
    template: PyReadonlyArrayDyn<'py, f64>,
    i0: usize,
    i1: usize,
) -> PyResult<(Bound<'py, PyArrayDyn<f64>>, usize)> {
    let xs = x.shape().to_vec();
    if xs.len() != 2 {
        return Err(PyValueError::new_err(format!("x has shape {xs:?}, expected (channels, samples)")));
    }
    let (nch, n) = (xs[0], xs[1]);
    let ts = template.shape().to_vec();
    if ts.len() != 2 || ts[0] != nch || ts[1] < 4 {
        return Err(PyValueError::new_err(format!("template has shape {ts:?}, expected ({nch}, p >= 4)")));
    }
    if !(i0 <= i1 && i1 <= n) || !(fs > 0.0) {
        return Err(PyValueError::new_err(format!("need 0 <= i0 <= i1 <= {n} and fs > 0 (got i0={i0}, i1={i1}, fs={fs})")));
    }
    let kps = slice(&kp, "kp")?;
    check_kp(kps)?;
    let (xsl, tsl) = (slice(&x, "x")?, slice(&template, "template")?);
    let p = ts[1];
    check_alloc("runout_subtract", nch.checked_mul(i1 - i0), 8)?;
    let out = py.detach(|| {
        guarded(|| {
            let mut out = out_buf(nch * (i1 - i0));
            order::runout_subtract(xsl, nch, fs, t0, kps, tsl, p, i0, i1, &mut out).map(|bad| (out, bad))
        })
    })?
    .map_err(core_err)?;
    Ok((to_py(py, out.0, &[nch, i1 - i0])?, out.1))
}

/// Arrays of a study call, borrowed for the duration of the call.
struct StudyArgs<'py> {
    rotor: Rotor,
    w: PyReadonlyArrayDyn<'py, f64>,
    kb: PyReadonlyArrayDyn<'py, f64>,
    cb: PyReadonlyArrayDyn<'py, f64>,
    probes_z: [f64; 4],
    u: Option<PyReadonlyArrayDyn<'py, C64>>,
    planes_z: PyReadonlyArrayDyn<'py, f64>,
    dirs: Option<PyReadonlyArrayDyn<'py, u8>>,
    spin: f64,
    errors: Vec<f64>,
    method: Method,
    seed: u64,
}

impl StudyArgs<'_> {
    fn study(&self) -> PyResult<Study<'_>> {
        let w = slice(&self.w, "w")?;
        let planes = slice(&self.planes_z, "planes_z")?;
        let e = &self.errors;
        let excitation = match (&self.u, &self.dirs) {
            (Some(u), None) => {
                if planes.len() != 2 || e.len() != 9 {
                    return Err(PyValueError::new_err("imbalance study: planes_z must hold 2 values and errors 9"));
                }
                Excitation::Imbalance {
                    u: slice(u, "u")?,
                    planes_z: [planes[0], planes[1]],
                    errors: SyncErrors {
                        amplitude_rel: e[0],
                        phase_rad: e[1],
                        noise_m: e[2],
                        keyphasor_rad: e[3],
                        delay_s: e[4],
                        probe_position_m: e[5],
                        mass_rel: e[6],
                        angle_rad: e[7],
                        speed_rel: e[8],
                    },
                }
            }
            (None, Some(d)) => {
                if e.len() != 5 {
                    return Err(PyValueError::new_err("impact study: errors must hold 5 values"));
                }
                Excitation::Impact {
                    planes_z: planes,
                    dirs: slice(d, "dirs")?,
                    spin: self.spin,
                    errors: ImpactErrors { frf_rel: e[0], force_cal_rel: e[1], impact_position_m: e[2], delay_s: e[3], probe_position_m: e[4] },
                }
            }
            _ => return Err(PyValueError::new_err("a study takes either imbalances u or impact directions dirs")),
        };
        Ok(Study {
            rotor: self.rotor,
            w,
            kb: slice(&self.kb, "kb")?,
            cb: slice(&self.cb, "cb")?,
            probes_z: self.probes_z,
            excitation,
            method: self.method,
            seed: self.seed,
        })
    }
}

#[allow(clippy::too_many_arguments)]
fn study_args<'py>(
    rotor: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    kb: PyReadonlyArrayDyn<'py, f64>,
    cb: PyReadonlyArrayDyn<'py, f64>,
    probes_z: PyReadonlyArrayDyn<'py, f64>,
    u: Option<PyReadonlyArrayDyn<'py, C64>>,
    planes_z: PyReadonlyArrayDyn<'py, f64>,
    dirs: Option<PyReadonlyArrayDyn<'py, u8>>,
    spin: f64,
    errors: PyReadonlyArrayDyn<'py, f64>,
    method: &str,
    seed: u64,
) -> PyResult<StudyArgs<'py>> {
    let z = slice(&probes_z, "probes_z")?;
    if z.len() != 4 {
        return Err(PyValueError::new_err(format!("probes_z has {} values, expected 4", z.len())));
    }
    let method = match method {
        "forces" => Method::Forces,
        "report" => Method::Report,
        m => return Err(PyValueError::new_err(format!("method must be 'forces' or 'report', got {m:?}"))),
    };
    Ok(StudyArgs {
        rotor: rotor_of(&rotor)?,
        probes_z: [z[0], z[1], z[2], z[3]],
        errors: slice(&errors, "errors")?.to_vec(),
        w,
        kb,
        cb,
        u,
        planes_z,
        dirs,
        spin,
        method,
        seed,
    })
}

type Stats<'py> = (
    Bound<'py, PyArrayDyn<u32>>,
    Bound<'py, PyArrayDyn<u32>>,
    Bound<'py, PyArrayDyn<u32>>,
    Bound<'py, PyArrayDyn<f64>>,
    Bound<'py, PyArrayDyn<f64>>,
);

/// Monte Carlo study (see study/mod.rs): trials t0..t1 at points p0..p1 simulated, perturbed,
/// identified and accumulated. Returns (counts (np, 16, BINS), finite, nonfinite, sum, sumsq
/// (np, 16)). Imbalance: u (runs, 2) complex, planes_z (2,), errors (9,); impacts: dirs (runs,)
/// u8, planes_z (runs,), spin, errors (5,).
#[pyfunction]
#[pyo3(signature = (rotor, w, kb, cb, probes_z, planes_z, errors, t0, t1, p0, p1, *, u=None, dirs=None, spin=0.0, method="forces", seed=0, counts=None))]
#[allow(clippy::too_many_arguments)]
fn study_accumulate<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    kb: PyReadonlyArrayDyn<'py, f64>,
    cb: PyReadonlyArrayDyn<'py, f64>,
    probes_z: PyReadonlyArrayDyn<'py, f64>,
    planes_z: PyReadonlyArrayDyn<'py, f64>,
    errors: PyReadonlyArrayDyn<'py, f64>,
    t0: u64,
    t1: u64,
    p0: usize,
    p1: usize,
    u: Option<PyReadonlyArrayDyn<'py, C64>>,
    dirs: Option<PyReadonlyArrayDyn<'py, u8>>,
    spin: f64,
    method: &str,
    seed: u64,
    counts: Option<Bound<'py, PyArrayDyn<u32>>>,
) -> PyResult<Stats<'py>> {
    let args = study_args(rotor, w, kb, cb, probes_z, u, planes_z, dirs, spin, errors, method, seed)?;
    let s = args.study()?;
    let np = p1.saturating_sub(p0);
    let m = [np, study::NCOEF];
    match counts {
        // add into the caller's running counts (no allocation per call); the rest is fresh
        Some(arr) => {
            let mut rw = arr.try_readwrite().map_err(|_| PyValueError::new_err("counts must be a writable array not in use elsewhere"))?;
            check_shape("counts", rw.shape(), &[np, study::NCOEF, study::BINS])?;
            let cs = rw.as_slice_mut().map_err(|_| PyValueError::new_err("counts must be a C-contiguous uint32 array"))?;
            check_alloc("study", np.checked_mul(study::NCOEF * 6), 4)?;
            let (mut fin, mut nonf, mut sm, mut sq) = (vec![0u32; np * 16], vec![0u32; np * 16], vec![0.0; np * 16], vec![0.0; np * 16]);
            py.detach(|| {
                guarded(|| {
                    let out = study::StatsMut { counts: cs, finite: &mut fin, nonfinite: &mut nonf, sum: &mut sm, sumsq: &mut sq };
                    study::accumulate_into(&s, t0, t1, p0, p1, out)
                })
            })?
            .map_err(core_err)?;
            drop(rw);
            Ok((arr, to_py(py, fin, &m)?, to_py(py, nonf, &m)?, to_py(py, sm, &m)?, to_py(py, sq, &m)?))
        }
        None => {
            check_alloc("study", np.checked_mul(study::NCOEF * (study::BINS + 6)), 4)?;
            let st = py.detach(|| guarded(|| study::accumulate(&s, t0, t1, p0, p1)))?.map_err(core_err)?;
            Ok((
                to_py(py, st.counts, &[np, study::NCOEF, study::BINS])?,
                to_py(py, st.finite, &m)?,
                to_py(py, st.nonfinite, &m)?,
                to_py(py, st.sum, &m)?,
                to_py(py, st.sumsq, &m)?,
            ))
        }
    }
}

/// The measured values of trials t0..t1 of a study, before identification: (q (trials, runs,
/// n, 4) at the channels, w_told (trials, n)). Same arguments as `study_accumulate`.
#[pyfunction]
#[pyo3(signature = (rotor, w, kb, cb, probes_z, planes_z, errors, t0, t1, *, u=None, dirs=None, spin=0.0, seed=0))]
#[allow(clippy::too_many_arguments)]
fn study_realize<'py>(
    py: Python<'py>,
    rotor: PyReadonlyArrayDyn<'py, f64>,
    w: PyReadonlyArrayDyn<'py, f64>,
    kb: PyReadonlyArrayDyn<'py, f64>,
    cb: PyReadonlyArrayDyn<'py, f64>,
    probes_z: PyReadonlyArrayDyn<'py, f64>,
    planes_z: PyReadonlyArrayDyn<'py, f64>,
    errors: PyReadonlyArrayDyn<'py, f64>,
    t0: u64,
    t1: u64,
    u: Option<PyReadonlyArrayDyn<'py, C64>>,
    dirs: Option<PyReadonlyArrayDyn<'py, u8>>,
    spin: f64,
    seed: u64,
) -> PyResult<(Bound<'py, PyArrayDyn<C64>>, Bound<'py, PyArrayDyn<f64>>)> {
    let args = study_args(rotor, w, kb, cb, probes_z, u, planes_z, dirs, spin, errors, "forces", seed)?;
    let s = args.study()?;
    let (nt, n, runs) = (t1.saturating_sub(t0) as usize, s.w.len(), s.runs());
    let total = nt.checked_mul(runs).and_then(|v| v.checked_mul(n * 4));
    check_alloc("study_realize", total, 16)?;
    let total = total.unwrap_or(0);
    let (q, wt) = py
        .detach(|| {
            guarded(|| {
                let mut q = vec![C64::new(0.0, 0.0); total];
                let mut wt = vec![0.0; nt * n];
                study::realize(&s, t0, t1, &mut q, &mut wt).map(|_| (q, wt))
            })
        })?
        .map_err(core_err)?;
    Ok((to_py(py, q, &[nt, runs, n, 4])?, to_py(py, wt, &[nt, n])?))
}

/// Percentiles of study histograms (see study::percentiles_of_counts): `counts` C-contiguous
/// uint32 or uint64 of any shape (..., BINS), `percentiles` (P,) -> (P, rows), rows = the
/// product of the leading axes.
#[pyfunction]
fn study_percentiles<'py>(py: Python<'py>, counts: &Bound<'py, PyAny>, percentiles: PyReadonlyArrayDyn<'py, f64>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    fn of<T: Copy + Into<u64> + Sync>(py: Python<'_>, cs: &[T], q: &[f64]) -> PyResult<Vec<f64>> {
        py.detach(|| {
            guarded(|| {
                let mut out = out_buf(cs.len() / study::BINS * q.len());
                study::percentiles_of_counts(cs, q, &mut out).map(|_| out)
            })
        })?
        .map_err(core_err)
    }
    let q = slice(&percentiles, "percentiles")?;
    let (len, out) = if let Ok(c) = counts.extract::<PyReadonlyArrayDyn<'py, u32>>() {
        let cs = slice(&c, "counts")?;
        (cs.len(), of(py, cs, q)?)
    } else if let Ok(c) = counts.extract::<PyReadonlyArrayDyn<'py, u64>>() {
        let cs = slice(&c, "counts")?;
        (cs.len(), of(py, cs, q)?)
    } else {
        return Err(PyValueError::new_err("counts must be a uint32 or uint64 array"));
    };
    to_py(py, out, &[q.len(), len / study::BINS])
}

/// Edges of the study histograms' bins: (BINS + 1,), bin b holds [edges[b], edges[b + 1]), the end
/// bins reach to -inf and +inf.
#[pyfunction]
fn study_bin_edges(py: Python<'_>) -> PyResult<Bound<'_, PyArrayDyn<f64>>> {
    let mut e: Vec<f64> = (0..study::BINS).map(|b| study::bin_edges(b).0).collect();
    e.push(f64::INFINITY);
    to_py(py, e, &[study::BINS + 1])
}

/// Wake the thread pool's helpers ahead of a parallel core call (rotorid_core::par::wake_helpers):
/// they spin for at most `max_wait_us` microseconds, or until the spin time (`SPIN_US`) after
/// the parallel calls made meanwhile, taking part in those calls.
#[pyfunction]
#[pyo3(signature = (max_wait_us = 2000.0))]
fn wake_pool(max_wait_us: f64) -> PyResult<()> {
    let longest = rotorid_core::par::MAX_SPIN.as_secs_f64() * 1e6;
    if !(max_wait_us.is_finite() && (0.0..=longest).contains(&max_wait_us)) {
        return Err(PyValueError::new_err(format!(
            "max_wait_us must be within 0 and {longest} (the longest a helper spins), got {max_wait_us}"
        )));
    }
    // through the pool the next call will use: in a forked child (whose inherited global pool has
    // no threads) that is the child's own pool, inside which waking is a no-op
    guarded(|| rotorid_core::par::wake_helpers(std::time::Duration::from_secs_f64(max_wait_us * 1e-6)))
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    LOADED_BY.get_or_init(std::process::id);
    // a misspelt cap is refused here, not silently ignored by the kernels' dispatch
    rotorid_core::lanes::simd_cap_from_env().map_err(core_err)?;
    rotorid_core::par::spin_time_from_env().map_err(core_err)?;
    rotorid_core::par::steer::steer_from_env().map_err(core_err)?;
    m.add("SIMD", rotorid_core::lanes::simd().name())?;
    m.add("SIMD_CPU", rotorid_core::lanes::simd_of_cpu().name())?;
    m.add("SPIN_US", rotorid_core::par::spin_time().as_secs_f64() * 1e6)?;
    m.add("STEER", rotorid_core::par::steer::steering())?;
    m.add_function(wrap_pyfunction!(forced_response, m)?)?;
    m.add_function(wrap_pyfunction!(py_identify, m)?)?;
    m.add_function(wrap_pyfunction!(py_modal, m)?)?;
    m.add_function(wrap_pyfunction!(forced_response_pedestal, m)?)?;
    m.add_function(wrap_pyfunction!(effective_coefficients, m)?)?;
    m.add_function(wrap_pyfunction!(modal_pedestal, m)?)?;
    m.add_function(wrap_pyfunction!(bearing_forces, m)?)?;
    m.add_function(wrap_pyfunction!(pedestal_fit, m)?)?;
    m.add_function(wrap_pyfunction!(series_impedance, m)?)?;
    m.add_function(wrap_pyfunction!(relative_std, m)?)?;
    m.add_function(wrap_pyfunction!(propagate, m)?)?;
    m.add_function(wrap_pyfunction!(identical_std, m)?)?;
    m.add_function(wrap_pyfunction!(check_covariances, m)?)?;
    m.add_function(wrap_pyfunction!(unknown_points, m)?)?;
    m.add_function(wrap_pyfunction!(flag_codes, m)?)?;
    m.add_function(wrap_pyfunction!(block_statistics, m)?)?;
    m.add_function(wrap_pyfunction!(wake_pool, m)?)?;
    m.add_function(wrap_pyfunction!(move_covariances, m)?)?;
    m.add_function(wrap_pyfunction!(sample_times, m)?)?;
    m.add_function(wrap_pyfunction!(imbalance_response, m)?)?;
    m.add_function(wrap_pyfunction!(apply_planes, m)?)?;
    m.add_function(wrap_pyfunction!(lti_run, m)?)?;
    m.add_function(wrap_pyfunction!(angle_resample, m)?)?;
    m.add_function(wrap_pyfunction!(order_vectors, m)?)?;
    m.add_function(wrap_pyfunction!(first_outside, m)?)?;
    m.add_function(wrap_pyfunction!(runout_subtract, m)?)?;
    m.add_function(wrap_pyfunction!(study_accumulate, m)?)?;
    m.add_function(wrap_pyfunction!(study_realize, m)?)?;
    m.add_function(wrap_pyfunction!(study_bin_edges, m)?)?;
    m.add_function(wrap_pyfunction!(study_percentiles, m)?)?;
    m.add("STUDY_BINS", study::BINS)?;
    m.add("STUDY_E0", study::E0)?;
    m.add("STUDY_SUB", study::stats::SUB)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
