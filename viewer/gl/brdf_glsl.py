"""GLSL glue generated from the BRDF specs.

For each model the spec gives a struct ``<name>_params`` (field names = parameter names:
rgb -> vec3, float -> float, choice -> int index, table -> nested struct, lobes -> vec4 array +
``<name>_count``, material -> ``<name>_model`` + ``<name>_offset``) and an unpack function that
reads the struct from the flat uniform block ``u_mat`` (vec4 array). ``pack_material`` writes the
same layout from Python, so a slider move is a uniform upload, never a recompile.

The generated ``brdf/dispatch.glsl`` includes every family file (``shaders/brdf/<name>.glsl``)
and defines ``vec3 brdf_eval(int model, int offset, vec3 wi, vec3 wo)``,
``vec3 brdf_terms(...)`` (F, D, G for the term views; -1 where a model has none) and the
sampling twins ``brdf_sample(model, offset, wo, u, out wi, out pdf, out lobe)`` (returns f cos / pdf; lobe: the
LOBE_* flags of the lobe it drew, as numpy's ``sample_lobe``),
``brdf_pdf(model, offset, wi, wo)``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from viewer import brdf
from viewer.brdf import spectral_fresnel, thin_film
from viewer.brdf.spec import ModelSpec, Param, Params
from viewer.gl.constants import MAT_VEC4
from viewer.gl.shader_folder import ShaderError, shader_root
from viewer.spectral.colorimetry import luminance



# ---------------------------------------------------------------- layout
def _size(param: Param) -> int:
    k = param.kind
    if k == "rgb":
        return 3
    if k == "choice" and param.spectral_table:
        return 2
    if k in ("float", "choice", "bool"):
        return 1
    if k == "table":
        return sum(_size(f) for f in param.fields)
    if k == "lobes":
        return 4 * param.max_items + 1
    if k == "material":
        return 2
    if k == "path":
        return 0
    raise AssertionError(k)


def block_size(spec: ModelSpec) -> int:
    return sum(_size(p) for p in spec.params) + spec.derived_size


def model_index(name: str) -> int:
    """The model id of a registry name, or of a file BRDF's program name (``custom:PATH``): the
    ids after the registry's, one per file (its slot, ``custom_slot``), so that the programs
    holding several files (traced chains, the GPU engine) tell them apart."""
    if is_custom(name):
        return len(brdf.names()) + custom_slot(name)
    return brdf.names().index(name)


_SLOTS: dict[str, int] = {}  # custom:PATH -> its slot, in the order the files were first used


def custom_slot(name: str) -> int:
    """The slot of the file BRDF ``custom:PATH`` in this process: 0 for the first file used, 1
    for the next... Its GLSL names carry the slot (``brdffile.prefix_for``, ``custom<k>_``), so
    that any set of files can share a program; the same file keeps its slot in every program."""
    slot = _SLOTS.get(name)
    if slot is None:
        slot = _SLOTS[name] = len(_SLOTS)
    return slot


def _custom_names(name: str) -> tuple[str, str, str]:
    """(GLSL function prefix, the file's name prefix, its include name) of ``custom:PATH``: the
    include is the file's name, or its whole path where a file of the same name in another
    folder took a slot before it (two such files can share a program)."""
    from viewer.brdf.brdffile import prefix_for
    from viewer.gl.file_brdf_glsl import include_name

    slot = custom_slot(name)
    path = Path(name[len(CUSTOM_PREFIX):])
    clash = any(Path(n[len(CUSTOM_PREFIX):]).name == path.name and k < slot for n, k in _SLOTS.items())
    return ("custom" if slot == 0 else f"custom{slot}"), prefix_for(slot), include_name(path.as_posix() if clash else path.name)


CUSTOM_PREFIX = "custom:"
_TABLES: dict = {}


def sampler_table(params, room: int | None = None) -> np.ndarray:
    """The generic sampler's table of a file material (``viewer.brdf.file_sampler``: per view
    node, a 2D table over the warped half vectors of the BRDF's f cos_i 4 (wo.h)), built from
    the file's f through its GLSL for the current parameters, at the sizes that fit ``room``
    floats (None: unbounded, the GPU engine's material texture). Cached per file, parameters
    and room."""
    import json

    from viewer.brdf import file_sampler

    model = brdf.model_of(params).of(params)
    sizes = file_sampler.sizes_for(room)
    if sizes is None:
        raise ValueError(f"material {model.bfile.path.name}: {room} floats are left for the sampler's table, "
                         f"it needs {file_sampler.size(file_sampler.SMALL[-1])}")
    key = (str(model.bfile.path), json.dumps(params.to_plain(), sort_keys=True), id(model), sizes)
    hit = _TABLES.get(key)
    if hit is not None:
        return hit

    def f(wi, wo):
        return luminance(np.asarray(model.eval(params, wi, wo), float))

    table = file_sampler.build(f, sizes)
    if len(_TABLES) > 256:
        _TABLES.clear()
    _TABLES[key] = table
    return table


def _generic_sampler() -> list[str]:
    """GLSL of the generic sampler over the table at float p.o + CUSTOM_T (layout and formulas:
    ``viewer.brdf.file_sampler``, whose sample / pdf it follows step for step; the sizes are
    read from the table, so a table of another size needs no recompile)."""
    from viewer.brdf import file_sampler as fs

    return f"""float custom_tab(custom_params p, int i) {{ return mat_f(p.o + CUSTOM_T + i); }}
float custom_d_cos(float cz, float a) {{  // GGX D cos theta_h of width a: the warp's density
    float d = cz * cz * (a * a - 1.0) + 1.0;
    return a * a / (PI * d * d) * cz;
}}
// the view node below wo (k) and the odds of the one above (w); az: the view's azimuth
void custom_view(custom_params p, vec3 wo, out int k, out float w, out float az) {{
    int nv = int(custom_tab(p, 2) + 0.5);
    az = (wo.x != 0.0 || wo.y != 0.0) ? atan(wo.y, wo.x) : 0.0;
    k = 0;
    w = 0.0;
    if (nv > 1) {{
        float x = clamp(sqrt(max(1.0 - wo.z, 0.0)) / {fs.VIEW_X_MAX!r} * float(nv - 1), 0.0, float(nv - 1));
        k = min(int(x), nv - 2);
        w = x - float(k);
    }}
}}
// the density of node k over (s, |phi|): P(i) P(j | i) / (ds dphi)
float custom_node_pdf(custom_params p, int k, float s, float ph) {{
    int nt = int(custom_tab(p, 3) + 0.5), nph = int(custom_tab(p, 4) + 0.5);
    int i = min(int(s * float(nt)), nt - 1);
    int j = min(int(ph / PI * float(nph)), nph - 1);
    int b = {fs.HEADER} + k * (nt + nt * nph);
    float m = custom_tab(p, b + i) - (i > 0 ? custom_tab(p, b + i - 1) : 0.0);
    int cb = b + nt + i * nph;
    float c = custom_tab(p, cb + j) - (j > 0 ? custom_tab(p, cb + j - 1) : 0.0);
    return m * c * float(nt * nph) / PI;
}}
float custom_table_pdf(custom_params p, vec3 wi, vec3 wo) {{
    vec3 h = wi + wo;
    float l = length(h);
    if (!(l > 0.0)) return 0.0;
    h /= l;
    float woh = dot(wo, h);
    if (h.z <= 0.0 || woh <= 0.0) return 0.0;
    float a = custom_tab(p, 0);
    float cz = clamp(h.z, 1e-12, 1.0);
    float t = max(1.0 - cz * cz, 0.0) / (cz * cz);
    float s = t / (a * a + t);
    int k;
    float w, az;
    custom_view(p, wo, k, w, az);
    float ph = abs(((h.x != 0.0 || h.y != 0.0) ? atan(h.y, h.x) : 0.0) - az);
    if (ph > PI) ph = TWO_PI - ph;
    float q = (1.0 - w) * custom_node_pdf(p, k, s, ph);
    if (w > 0.0) q += w * custom_node_pdf(p, k + 1, s, ph);
    // per solid angle of h: q / 2 (the folded sign) * 2 pi D cos; of wi: / 4 (wo.h)
    return q * PI * custom_d_cos(cz, a) / (4.0 * woh);
}}
float custom_pdf(custom_params p, vec3 wi, vec3 wo) {{
    if (wi.z <= 0.0 || wo.z <= 0.0) return 0.0;
    float c = custom_tab(p, 1);
    return c * wi.z * INV_PI + (c < 1.0 ? (1.0 - c) * custom_table_pdf(p, wi, wo) : 0.0);
}}
// the band of u under the n CDF values at table float b: the first whose CDF exceeds u; t: u's
// position in it
int custom_find(custom_params p, int b, int n, float u, out float t) {{
    int lo = 0, hi = n - 1;
    for (int it = 0; it < {fs.MAX_BANDS.bit_length()}; ++it) {{  // a fixed count: n <= MAX_BANDS
        int mid = (lo + hi) / 2;
        if (lo < hi) {{
            if (custom_tab(p, b + mid) <= u) lo = mid + 1; else hi = mid;
        }}
    }}
    float c0 = lo > 0 ? custom_tab(p, b + lo - 1) : 0.0;
    t = clamp((u - c0) / max(custom_tab(p, b + lo) - c0, 1e-30), 0.0, 1.0);
    return lo;
}}
vec3 custom_sample(custom_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {{
    lobe = LOBE_REFLECTION | LOBE_GLOSSY;  // a file BRDF: smooth reflection (its lobes)
    float c = custom_tab(p, 1);
    if (u.z < c) {{  // cosine-weighted
        float r = sqrt(u.x);
        float phi = TWO_PI * u.y;
        wi = vec3(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - u.x)));
    }} else {{  // a half vector from the table: the view node, the band of s, then of |phi|
        int nt = int(custom_tab(p, 3) + 0.5), nph = int(custom_tab(p, 4) + 0.5);
        int k;
        float w, az, ts, tp;
        custom_view(p, wo, k, w, az);
        if ((u.z - c) / (1.0 - c) >= 1.0 - w) k += 1;
        int b = {fs.HEADER} + k * (nt + nt * nph);
        int i = custom_find(p, b, nt, u.x, ts);
        float s = min((float(i) + ts) / float(nt), {float(np.float32(1.0 - 1e-7))!r});
        float sg = u.y < 0.5 ? 1.0 : -1.0;
        float uy = u.y < 0.5 ? 2.0 * u.y : 2.0 * u.y - 1.0;
        int j = custom_find(p, b + nt + i * nph, nph, uy, tp);
        float phi = az + sg * (float(j) + tp) * (PI / float(nph));
        float a = custom_tab(p, 0);
        float cz = 1.0 / sqrt(1.0 + a * a * s / (1.0 - s));
        float sz = sqrt(max(0.0, 1.0 - cz * cz));
        vec3 h = vec3(sz * cos(phi), sz * sin(phi), cz);
        wi = 2.0 * dot(wo, h) * h - wo;
    }}
    pdf = custom_pdf(p, wi, wo);
    if (!(pdf > 0.0)) {{ pdf = 0.0; return vec3(0.0); }}
    return custom_eval(p, wi, wo) * wi.z / pdf;
}}""".splitlines()


def is_custom(name: str) -> bool:
    """``name`` is a file BRDF's program name ``custom:PATH`` (see ``models_used``)."""
    return name.startswith(CUSTOM_PREFIX)


def custom_file(name: str):
    """The parsed ``.brdf`` file of the program name ``custom:PATH``; a file that no longer reads
    or parses (edited while the window runs) is a ShaderError naming ``FILE.brdf:LINE``, as a
    compile error is, so hot reload keeps the last good program and shows it."""
    import re

    from viewer import ViewerError

    try:
        return brdf.load(name[len(CUSTOM_PREFIX):]).bfile
    except ViewerError as e:
        msg = str(e).splitlines()[0]
        m = re.match(r"([^:\s]+\.brdf):(\d+):\s*(.*)", msg)
        if m:
            raise ShaderError(msg, m.group(1), int(m.group(2)), detail=m.group(3)) from None
        raise ShaderError(msg, Path(name[len(CUSTOM_PREFIX):]).name, None, detail=msg) from None


def custom_virtual(only) -> dict[str, str]:
    """The virtual include ``NAME.brdf`` (the file's GLSL block) of each file BRDF in ``only``."""
    from viewer.gl.file_brdf_glsl import virtual_files

    out: dict[str, str] = {}
    for n in only or ():
        if is_custom(n):
            _, prefix, include = _custom_names(n)
            out.update(virtual_files(custom_file(n), prefix=prefix, name=include))
    return out


def _custom_glue(name: str) -> list[str]:
    """The family functions of a file BRDF over its block: custom_params (its offset),
    custom_eval (the file's BRDF above the surface, negative values as 0), and custom_sample /
    custom_pdf, the sampler that works for any BRDF (the twin of ``viewer.brdf.file_sampler``):
    cosine-weighted directions mixed with half vectors drawn from a table of the BRDF for the
    current parameters (``sampler_table``), with the exact pdf of the mixture."""
    import re

    from viewer.gl.file_brdf_glsl import n_floats, set_params_glsl

    bfile = custom_file(name)
    c, prefix, include = _custom_names(name)
    sets = set_params_glsl(bfile, read=lambda k: f"mat_f(p.o + {k})", prefix=prefix)
    lines = [f'#include "{include}"',
            "struct custom_params {\n    int o;\n};",
            "custom_params custom_unpack(int o) { custom_params p; p.o = o; return p; }",
            "vec3 custom_eval(custom_params p, vec3 wi, vec3 wo) {",
            "    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);",
            f"    {sets}",
            "    vec3 f = vec3(bxf_BRDF(wi, wo, vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0)));",
            "    return max(f, vec3(0.0));",
            "}",
            f"#define CUSTOM_T {n_floats(bfile)}  // the sampler's table after the parameters",
            *_generic_sampler(), ""]
    if bfile.has_sampler:
        # the file's own sampler (its isFunc), where no MIS weight needs the pdf of a direction it
        # did not draw (FILE_SAMPLERS: the GPU engine with BSDF or light sampling alone, or with
        # no environment): its direction and pdf, the weight f cos / pdf from the file's BRDF
        from viewer.brdf.brdffile import sampler_takes_view

        view = "wo, " if sampler_takes_view(bfile) else ""
        i = lines.index("vec3 custom_sample(custom_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {")
        lines[i:i + 1] = [
            "#ifdef FILE_SAMPLERS",
            "vec3 custom_sample(custom_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {",
            f"    {sets}",
            "    lobe = LOBE_REFLECTION | LOBE_GLOSSY;",
            "    wi = vec3(0.0, 0.0, 1.0);",
            "    pdf = 0.0;",
            f"    bxf_sampleBRDF({view}u.x, u.y, vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), wi, pdf);",
            "    if (!(pdf > 0.0) || !(wi.z > 0.0) || wo.z <= 0.0) { pdf = 0.0; return vec3(0.0); }",
            "    return custom_eval(p, wi, wo) * wi.z / pdf;",
            "}",
            "vec3 custom_sample_generic(custom_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {",
            "#else",
            "vec3 custom_sample(custom_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {",
            "#endif"]
    # the slot's names: custom<k>_... and CUSTOM<k>_T / _N, the file's globals with its prefix
    return lines[:1] + [re.sub(r"\bcustom_", f"{c}_", re.sub(r"\bCUSTOM_([TN])\b", f"{c.upper()}_\\1", x))
                        .replace("bxf_BRDF(", f"{prefix}BRDF(").replace("bxf_sampleBRDF(", f"{prefix}sampleBRDF(")
                        for x in lines[1:]]


def _pack_fields(params_spec, values, out: list, tail: list, base_offset_fn):
    for p in params_spec:
        v = values[p.name]
        k = p.kind
        if k == "rgb":
            out.extend(float(x) for x in np.asarray(v).reshape(3))
        elif k in ("float", "bool"):
            out.append(float(v))
        elif k == "choice":
            out.append(float(p.choices.index(v)))
            if p.spectral_table:  # the material's RGB Fresnel table, appended after the block
                # (with a thin film also the base's n, k at the film's wavelengths after it)
                tab = spectral_fresnel.packed(v) if v != "none" else None
                if tab is not None and thin_film.active(values):
                    tab = np.concatenate([tab, thin_film.packed_base(v)])
                out.append(float(base_offset_fn(tab)) if tab is not None else 0.0)
        elif k == "table":
            _pack_fields(p.fields, v, out, tail, base_offset_fn)
        elif k == "lobes":
            for i in range(p.max_items):
                if i < len(v):
                    vals = [float(v[i][f.name]) for f in p.fields]
                    out.extend((vals + [0.0] * 4)[:4])
                else:
                    out.extend([0.0] * 4)
            out.append(float(len(v)))
        elif k == "material":
            out.append(float(model_index(v.model)))
            out.append(float(base_offset_fn(v)))
        elif k != "path":
            raise AssertionError(k)


def pack_material(params: Params, offset: int = 0, limit: int | None = 4 * MAT_VEC4) -> tuple[int, np.ndarray]:
    """(model index, float32 array) for the uniform block, starting at float ``offset``.

    Nested materials (the layered model's base) are appended after the main block; their
    offset is stored as an absolute float index into u_mat. ``limit``: the floats the block
    holds (None: no bound, for a material texture holding many materials)."""
    if brdf.is_file(params):  # a file BRDF: its declarations' floats
        from viewer.gl.file_brdf_glsl import n_floats, param_floats

        bfile = brdf.model_of(params).of(params).bfile
        room = None if limit is None else limit - offset - n_floats(bfile)
        data = np.concatenate([param_floats(bfile, params)[: n_floats(bfile)],
                               sampler_table(params, room)]).astype(np.float32)
        if limit is not None and offset + data.size > limit:
            raise ValueError(f"material {bfile.path.name} needs {data.size} floats; u_mat holds {4 * MAT_VEC4}")
        return model_index(CUSTOM_PREFIX + str(bfile.path)), data
    spec = brdf.get(params.model).spec
    main: list[float] = []
    tail: list[float] = []
    main_size = block_size(spec)

    def base_offset(sub):
        start = offset + main_size + len(tail)
        if isinstance(sub, np.ndarray):  # a table (spectral Fresnel)
            tail.extend(sub.tolist())
            return start
        _, arr = pack_material(sub, start, limit)
        tail.extend(arr.tolist())
        return start

    _pack_fields(spec.params, params, main, tail, base_offset)
    if spec.derived_size:
        extra = [float(x) for x in spec.derived(params)]
        assert len(extra) == spec.derived_size, (params.model, len(extra))
        main.extend(extra)
    assert len(main) == main_size, (params.model, len(main), main_size)
    data = np.array(main + tail, dtype=np.float32)
    if limit is not None and offset + data.size > limit:
        raise ValueError(f"material {params.model} needs {data.size} floats; u_mat holds {4 * MAT_VEC4}")
    return model_index(params.model), data


def uniform_block(params: Params) -> tuple[int, np.ndarray]:
    """Model index and the whole u_mat contents (float32, 4 * MAT_VEC4) for one material."""
    idx, data = pack_material(params)
    block = np.zeros(4 * MAT_VEC4, dtype=np.float32)
    block[: data.size] = data
    return idx, block


# ---------------------------------------------------------------- GLSL generation
def _glsl_decls(struct_name: str, params_spec, structs: list[str]) -> list[str]:
    lines = []
    for p in params_spec:
        k = p.kind
        if k == "rgb":
            lines.append(f"    vec3 {p.name};")
        elif k == "float":
            lines.append(f"    float {p.name};")
        elif k == "bool":
            lines.append(f"    bool {p.name};")
        elif k == "choice":
            lines.append(f"    int {p.name}; // " + ", ".join(f"{i} = {c}" for i, c in enumerate(p.choices)))
            if p.spectral_table:
                lines.append(f"    int {p.name}_offset; // its RGB Fresnel table in u_mat")
        elif k == "table":
            sub = f"{struct_name}_{p.name}_t"
            structs.append(_struct(sub, p.fields, structs))
            lines.append(f"    {sub} {p.name};")
        elif k == "lobes":
            lines.append(f"    vec4 {p.name}[{p.max_items}]; // " + ", ".join(f.name for f in p.fields))
            lines.append(f"    int {p.name}_count;")
        elif k == "material":
            lines.append(f"    int {p.name}_model;")
            lines.append(f"    int {p.name}_offset;")
    return lines


def _struct(name, params_spec, structs) -> str:
    body = _glsl_decls(name, params_spec, structs)
    return f"struct {name} {{\n" + "\n".join(body) + "\n};\n"


def _glsl_reads(params_spec, target: str, o: list[int], fixed: dict | None = None) -> list[str]:
    lines = []
    for p in params_spec:
        k = p.kind
        at = o[0]
        if k == "choice" and fixed and p.name in fixed:
            # a compile-time constant: the compiler drops the branches of the other choices
            lines.append(f"    {target}.{p.name} = {int(fixed[p.name])}; // fixed: {p.choices[fixed[p.name]]}")
            if p.spectral_table:
                lines.append(f"    {target}.{p.name}_offset = int(mat_f(o + {at + 1}) + 0.5);")
        elif k == "rgb":
            lines.append(f"    {target}.{p.name} = vec3(mat_f(o + {at}), mat_f(o + {at + 1}), mat_f(o + {at + 2}));")
        elif k == "float":
            lines.append(f"    {target}.{p.name} = mat_f(o + {at});")
        elif k == "bool":
            lines.append(f"    {target}.{p.name} = mat_f(o + {at}) > 0.5;")
        elif k == "choice":
            lines.append(f"    {target}.{p.name} = int(mat_f(o + {at}) + 0.5);")
            if p.spectral_table:
                lines.append(f"    {target}.{p.name}_offset = int(mat_f(o + {at + 1}) + 0.5);")
        elif k == "table":
            lines.extend(_glsl_reads(p.fields, f"{target}.{p.name}", o))
            if p.name == "thin_film" and any(f.name == "thickness_top_nm" for f in p.fields):
                # a film thinning with height (viewer/brdf/thin_film.py): its thickness here (a
                # layered coat's film reads its tables at the bottom thickness instead)
                t = f"{target}.{p.name}"
                lines.append(f"    if ({t}.thickness_top_nm >= 0.0) {t}.thickness_nm = "
                             f"mix({t}.thickness_nm, {t}.thickness_top_nm, brdf_film_height);")
            continue
        elif k == "lobes":
            lines.append(f"    for (int i = 0; i < {p.max_items}; ++i)")
            lines.append(f"        {target}.{p.name}[i] = vec4(mat_f(o + {at} + 4 * i), mat_f(o + {at} + 4 * i + 1),"
                         f" mat_f(o + {at} + 4 * i + 2), mat_f(o + {at} + 4 * i + 3));")
            lines.append(f"    {target}.{p.name}_count = int(mat_f(o + {at + 4 * p.max_items}) + 0.5);")
        elif k == "material":
            lines.append(f"    {target}.{p.name}_model = int(mat_f(o + {at}) + 0.5);")
            lines.append(f"    {target}.{p.name}_offset = int(mat_f(o + {at + 1}) + 0.5) + MAT_ROW(o);")
        o[0] += _size(p)
    return lines


def family_source(name: str) -> str:
    if is_custom(name):
        return "\n".join(_custom_glue(name))
    path = shader_root() / "brdf" / f"{name}.glsl"  # the hot-reload / BRDF_VIEWER_SHADERS folder
    try:
        return path.read_text()
    except OSError as e:
        raise ShaderError(f"shaders/brdf/{name}.glsl: the GLSL twin of registered model {name!r} "
                          f"cannot be read ({e.strerror})", f"brdf/{name}.glsl") from None


def models_used(params: Params) -> tuple[str, ...]:
    """The models a material needs in its program: itself and any nested base material; a file
    BRDF is ``custom:PATH`` (its program holds that file's GLSL)."""
    if brdf.is_file(params):  # validated: an absolute path (no load: the name of the program)
        return (CUSTOM_PREFIX + str(Path(params["file"]).expanduser().resolve()),)
    out = [params.model]
    for v in params.values():
        if isinstance(v, Params) and v.model:
            out.extend(models_used(v))
    return tuple(dict.fromkeys(out))


def film_kinds(params: Params) -> set[str]:
    """Which thin films a material needs compiled: "own" where it or a material nested in it
    carries ``thin_film`` (the wavelength loop of common/fresnel.glsl), "coat" where a table
    parameter of one does (a layered model's ``coating.thin_film``, read from tables the CPU
    computes: viewer/brdf/layered.py)."""
    out = set()
    if "thin_film" in params and thin_film.active(params):   # its own film (thin_film.active: the one test)
        out.add("own")
    for v in params.values():
        if isinstance(v, Params):
            if v.model:
                out |= film_kinds(v)
            elif thin_film.active(v):
                out.add("coat")
    return out


def measured_aniso(params: Params) -> bool:
    """Whether a material is (or nests) a measured material with an anisotropic (MIT) table."""
    from viewer.brdf.measured import is_aniso

    if not brdf.is_measured(params):
        return False
    nested = [v for v in params.values() if isinstance(v, Params) and v.model and brdf.is_measured(v)]
    return any(measured_aniso(v) for v in nested) if nested else is_aniso(params)


def program_defines(materials) -> dict[str, str]:
    """The ``#define``s a program needs for ``materials`` (an iterable of Params), the one place
    every program (forward pass, GPU albedo tables, GPU engine, tests) decides them:
    MEASURED_TEXTURE where one is or nests a measured table (shaders/brdf/measured.glsl reads it
    from a 3D texture; MEASURED_ANISO too where that table is an MIT anisotropic one), THIN_FILM where one (or its base) has a film of its own
    (common/fresnel.glsl compiles the film's wavelength loop only then), COAT_FILM where a
    layered coating has one (shaders/brdf/layered.glsl reads its precomputed tables: no loop)."""
    materials = list(materials)
    out = {}
    if any(brdf.is_measured(p) for p in materials):
        out["MEASURED_TEXTURE"] = "1"
        if any(measured_aniso(p) for p in materials):
            out["MEASURED_ANISO"] = "1"
    kinds = set().union(*(film_kinds(p) for p in materials)) if materials else set()
    if "own" in kinds:
        out["THIN_FILM"] = "1"
    if "coat" in kinds:
        out["COAT_FILM"] = "1"
    return out


def choice_constants(params: Params) -> dict[str, dict[str, int]]:
    """{model: {choice parameter: index}} of a material and its nested base, for
    ``generate_dispatch(fixed=...)``."""
    out: dict[str, dict[str, int]] = {}
    spec = brdf.get(params.model).spec
    out[params.model] = {p.name: p.choices.index(params[p.name]) for p in spec.params if p.kind == "choice"}
    for v in params.values():
        if isinstance(v, Params) and v.model:
            out.update(choice_constants(v))
    return out


def _material_reads(texture_width: int | None) -> list[str]:
    """How the dispatch reads float i of the materials: from the uniform block u_mat, or with
    MAT_TEXTURE from one row of MAT_VEC4 texels per material; or, given ``texture_width``, from
    one texture holding every material one after another, texel t at (t % width, t / width)
    (the GPU engine: offsets are absolute, so MAT_ROW is 0)."""
    if texture_width is not None:
        w = int(texture_width)
        assert w > 0 and w & (w - 1) == 0, "the material texture's width must be a power of two"
        return ["// every material of the scene one after another: texel t at (t % width, t / width)",
                "uniform sampler2D u_mat_tex;",
                f"float mat_f(int i) {{ int t = i >> 2; return texelFetch(u_mat_tex, ivec2(t & {w - 1}, "
                f"t >> {w.bit_length() - 1}), 0)[i & 3]; }}",
                "#define MAT_ROW(o) 0"]
    return ["#ifdef MAT_TEXTURE",
            "// every material of the scene, one row of MAT_VEC4 texels each: float i of the block",
            "// at offset 256 r is row r's (the traced specular chains shade the surfaces they hit)",
            "uniform sampler2D u_mat_tex;",
            f"float mat_f(int i) {{ return texelFetch(u_mat_tex, ivec2((i & {4 * MAT_VEC4 - 1}) >> 2, i >> {(4 * MAT_VEC4).bit_length() - 1}), 0)[i & 3]; }}",
            f"#define MAT_ROW(o) ((o) & ~{4 * MAT_VEC4 - 1})",
            "#else",
            f"uniform vec4 u_mat[{MAT_VEC4}];",
            "float mat_f(int i) { return u_mat[i >> 2][i & 3]; }",
            "#define MAT_ROW(o) 0",
            "#endif"]


def generate_dispatch(only: tuple[str, ...] | None = None, fixed: dict[str, dict[str, int]] | None = None,
                      texture_width: int | None = None) -> str:
    """The source of the virtual file ``brdf/dispatch.glsl``.

    ``only`` restricts the program to those models (the renderer compiles one program per
    material model: software GL pays for every branch of an uber-shader, ~3x here); None
    includes every registered model (tests and ``--check``). ``fixed`` ({model: {choice:
    index}}, see ``choice_constants``) compiles those choices in as constants instead of
    reading them from u_mat: software GL runs every branch a uniform disables, and the
    samplers' branches (e.g. Beckmann's Newton iteration) are costly. ``texture_width``: read
    the materials from one texture of that width holding all of them (see ``_material_reads``)."""
    out = ["// Generated by viewer/gl/brdf_glsl.py from the BRDF specs. Do not edit.",
           '#include "common/math.glsl"',
           '#include "common/lobes.glsl"',
           "// the shading point's relative height on its object, 0 bottom .. 1 top: a thin film's",
           "// thickness_top_nm applies there (the forward pass sets it; elsewhere the bottom's)",
           "float brdf_film_height = 0.0;"] + _material_reads(texture_width)
    # model ids by name (every registered model, so a nesting model can test its base's model)
    out.extend(f"#define BRDF_MODEL_{name.upper()} {model_index(name)}" for name in brdf.names())
    out.append("")
    plain, nesting = [], []
    customs = [n for n in (only or ()) if is_custom(n)]
    for name in list(brdf.names()) + customs:
        if only is not None and name not in only:
            continue
        if is_custom(name):
            plain.append(name)
            continue
        spec = brdf.get(name).spec
        (nesting if spec.nests_material else plain).append(name)
        structs: list[str] = []
        main = _struct(f"{name}_params", spec.params, structs)
        n_copy = spec.derived_size if spec.derived_copy is None else spec.derived_copy
        if spec.derived_size:
            main = main[:-3] + f"    float derived[{max(n_copy, 1)}];\n    int derived_at;\n}};\n"
        out.extend(structs)
        out.append(main)
        out.append(f"{name}_params {name}_unpack(int o) {{")
        out.append(f"    {name}_params p;")
        o = [0]
        out.extend(_glsl_reads(spec.params, "p", o, (fixed or {}).get(name)))
        if spec.derived_size:
            out.append(f"    for (int i = 0; i < {n_copy}; ++i) p.derived[i] = mat_f(o + {o[0]} + i);")
            out.append(f"    p.derived_at = o + {o[0]};")
        out.append("    return p;\n}\n")

    def has_terms(n):
        return f"{n}_terms(" in family_source(n)

    def dispatch(fn_name, names_, fallback, kind):
        lines = [f"vec3 {fn_name}(int model, int o, vec3 wi, vec3 wo) {{"]
        for name in names_:
            n = _custom_names(name)[0] if is_custom(name) else name
            if is_custom(name) and kind != "eval":
                continue  # a file BRDF has no separate terms
            if kind == "eval":
                lines.append(f"    if (model == {model_index(name)}) return {n}_eval({n}_unpack(o), wi, wo);")
            elif has_terms(name):
                lines.append(f"    if (model == {model_index(name)}) return {n}_terms({n}_unpack(o), wi, wo);")
        lines.append(f"    return {fallback};\n}}\n")
        return lines

    for n in plain:
        if is_custom(n):
            out.extend(_custom_glue(n))
        else:
            out.append(f'#include "brdf/{n}.glsl"')
    out.append("")
    out.extend(dispatch("brdf_eval_base", plain, "vec3(0.0)", "eval"))
    out.extend(_sampling_dispatch("base", plain, None))
    for n in nesting:
        out.append(f'#include "brdf/{n}.glsl"')
    out.append("")
    out.extend(dispatch("brdf_eval_nested", nesting, "brdf_eval_base(model, o, wi, wo)", "eval"))
    out.extend(_sampling_dispatch("nested", nesting, "base"))
    out.append("// Evaluate the BRDF of the material packed at float offset o of u_mat (no cosine).")
    out.append("vec3 brdf_eval(int model, int o, vec3 wi, vec3 wo) { return brdf_eval_nested(model, o, wi, wo); }\n")
    out.extend(_SAMPLING_API)
    out.extend(dispatch("brdf_terms", plain + nesting, "vec3(-1.0)", "terms"))
    return "\n".join(out)


def _sampling_dispatch(level: str, names_, fallback: str | None) -> list[str]:
    """brdf_sample_<level> and brdf_pdf_<level> over the models ``names_`` (the families'
    ``<name>_sample`` / ``<name>_pdf``); models not listed go to the ``fallback`` level (None: a
    failed sample, pdf 0, no lobe)."""
    def src(n):
        return family_source(n)

    sample = [f"vec3 brdf_sample_{level}(int model, int o, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {{"]
    pdf = [f"float brdf_pdf_{level}(int model, int o, vec3 wi, vec3 wo) {{"]
    for name in names_:
        i = model_index(name)
        n = _custom_names(name)[0] if is_custom(name) else name
        if f"{n}_sample(" in src(name):
            sample.append(f"    if (model == {i}) return {n}_sample({n}_unpack(o), wo, u, wi, pdf, lobe);")
        if f"{n}_pdf(" in src(name):
            pdf.append(f"    if (model == {i}) return {n}_pdf({n}_unpack(o), wi, wo);")
    if fallback is None:
        sample.append("    wi = vec3(0.0, 0.0, 1.0);\n    pdf = 0.0;\n    lobe = LOBE_NONE;\n    return vec3(0.0);\n}\n")
        pdf.append("    return 0.0;\n}\n")
    else:
        sample.append(f"    return brdf_sample_{fallback}(model, o, wo, u, wi, pdf, lobe);\n}}\n")
        pdf.append(f"    return brdf_pdf_{fallback}(model, o, wi, wo);\n}}\n")
    return sample + pdf


_SAMPLING_API = """// Importance sampling of the material at float offset o (twins of the numpy sample_lobe / pdf):
// returns the weight f |cos_i| / pdf; wi, pdf and the lobe drawn out (LOBE_* flags: one side,
// its kind; a DELTA one is discrete: no light sampling, no MIS). A failed sample has weight 0 and
// pdf 0. A delta lobe's pdf is the probability of choosing it (mirror: 1; smooth glass: R or
// 1 - R), and brdf_pdf / brdf_eval are 0 there. u: three uniforms in [0, 1); u.x, u.y as numpy's
// u[:, 0], u[:, 1]; u.z only where numpy splits u[:, 0] in two (rough glass, layered lobe choice).
vec3 brdf_sample(int model, int o, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    return brdf_sample_nested(model, o, wo, u, wi, pdf, lobe);
}
// The pdf (per solid angle) with which brdf_sample draws wi; 0 for delta lobes.
float brdf_pdf(int model, int o, vec3 wi, vec3 wo) { return brdf_pdf_nested(model, o, wi, wo); }
""".splitlines()


def glsl_u(params: Params, u: np.ndarray) -> np.ndarray:
    """The GLSL ``u`` (N, 3) that makes ``brdf_sample`` draw what numpy's ``sample`` draws from
    ``u`` (N, 2): (u0, u1, 0), except for models whose numpy sample splits u[:, 0] into a lobe
    choice and a continuous part (``split_uniform``; the module's ``splits_u(p)`` hook says so),
    where GLSL takes them as (continuous, u1, choice)."""
    from viewer.brdf.sampling import split_uniform

    u = np.asarray(u, dtype=np.float64)
    hook = brdf.get(params.model).hook("splits_u")
    if hook is not None and hook(params):
        choice, cont = split_uniform(u[:, 0])
        return np.stack([cont, u[:, 1], choice], axis=1)
    return np.concatenate([u[:, :2], np.zeros((len(u), 1))], axis=1)


if __name__ == "__main__":
    import sys

    if "--print" in sys.argv:
        print(generate_dispatch())
