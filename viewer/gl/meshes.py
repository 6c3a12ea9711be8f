"""The objects' geometry on the GPU: one vertex and index buffer per mesh, shared by every object
that uses it, and the instanced draws of the rasterizer (the objects that share a mesh and a
material are one draw, their model and normal matrices per-instance attributes: ``instance_data``,
``shaders/passes/forward.vert``). ``MeshCache`` holds the buffers of the meshes in use."""

from __future__ import annotations

import math

import numpy as np


def group_by(items, key) -> list[list]:
    """``items`` in groups of equal ``key(item)``, the groups in order of first appearance."""
    groups: dict = {}
    for it in items:
        groups.setdefault(key(it), []).append(it)
    return list(groups.values())


INSTANCE_FLOATS = 25   # per instance: the model matrix (16) and the normal matrix (9), column-major


def instance_data(objects) -> np.ndarray:
    """(N, 25) float32 per-instance attributes of ``objects`` for ``in_model`` and
    ``in_normal_matrix`` (shaders/passes/forward.vert): ``SceneObject.model_matrix`` for all of
    them at once, T(translate) R_y S(scale), and its inverse transpose R_y S^-1 (R_y is
    orthonormal), both column-major as GLSL reads them."""
    n = len(objects)
    out = np.empty((n, INSTANCE_FLOATS), np.float32)
    if n == 0:
        return out
    t = np.array([o.translate for o in objects], np.float64).reshape(n, 3)
    sc = np.array([np.broadcast_to(np.asarray(o.scale, np.float64), (3,)) for o in objects])
    ang = [math.radians(o.rotate_y_deg) for o in objects]
    c = np.array([math.cos(a) for a in ang])
    sn = np.array([math.sin(a) for a in ang])
    rot = np.zeros((n, 3, 3))
    rot[:, 0, 0], rot[:, 0, 2], rot[:, 1, 1], rot[:, 2, 0], rot[:, 2, 2] = c, sn, 1.0, -sn, c
    m = np.zeros((n, 4, 4))
    m[:, :3, :3] = rot * sc[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    nrm = rot / sc[:, None, :]
    out[:, :16] = m.transpose(0, 2, 1).reshape(n, 16)      # column-major
    out[:, 16:] = nrm.transpose(0, 2, 1).reshape(n, 9)
    return out


class GpuMesh:
    """Vertex and index buffers of one MeshData, shared by every object that uses it, and its
    per-instance buffer: each draw renders all the instances written by ``draw`` at once (one
    draw per mesh and material instead of one per object). One vertex array per program."""

    def __init__(self, ctx, mesh):
        data = np.hstack([mesh.positions, mesh.normals, mesh.tangents]).astype("f4")
        self.vbo = ctx.buffer(np.ascontiguousarray(data).tobytes())
        self.ibo = ctx.buffer(np.ascontiguousarray(mesh.indices, dtype="u4").tobytes())
        self.inst = ctx.buffer(reserve=4 * INSTANCE_FLOATS, dynamic=True)
        self.ctx = ctx
        self.vaos = {}

    def vao(self, prog):
        key = id(prog)
        if key not in self.vaos:
            # attributes the compiler dropped (e.g. the tangent when no model uses it) are skipped
            content = []
            for buf, attrs, per in ((self.vbo, (("in_position", "3f", 12), ("in_normal", "3f", 12),
                                                ("in_tangent", "4f", 16)), ""),
                                    (self.inst, (("in_model", "16f", 64), ("in_normal_matrix", "9f", 36)), "/i")):
                fmt, names = [], []
                for name, f, size in attrs:
                    if name in prog:
                        fmt.append(f)
                        names.append(name)
                    else:
                        fmt.append(f"{size}x")
                if names:
                    content.append((buf, " ".join(fmt) + per, *names))
            self.vaos[key] = self.ctx.vertex_array(prog, content, index_buffer=self.ibo, index_element_size=4)
        return self.vaos[key]

    def draw(self, prog, instances: np.ndarray):
        """Render the mesh once per row of ``instances`` ((N, 25) float32, ``instance_data``)."""
        data = np.ascontiguousarray(instances, np.float32).tobytes()
        if not data:
            return
        self.inst.orphan(len(data))   # fresh storage: a draw still reading the old rows is not waited for
        self.inst.write(data)
        self.vao(prog).render(instances=len(instances))

    def release(self):
        for v in self.vaos.values():
            v.release()
        self.vbo.release()
        self.ibo.release()
        self.inst.release()


class MeshCache:
    """The ``GpuMesh`` of every mesh drawn so far, by the mesh's identity (a mesh replaced by
    another at the same address is uploaded again)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._meshes: dict[int, tuple[object, GpuMesh]] = {}

    def get(self, mesh) -> GpuMesh:
        """The GPU buffers of ``mesh`` (a ``MeshData``), made on first use."""
        key = id(mesh)
        hit = self._meshes.get(key)
        if hit is None or hit[0] is not mesh:
            if hit is not None:
                hit[1].release()
            hit = (mesh, GpuMesh(self.ctx, mesh))
            self._meshes[key] = hit
        return hit[1]

    def draw_objects(self, objects, prog):
        """Draw ``objects`` with ``prog``: one instanced draw per mesh they use, in order of
        first appearance (the shadow and thickness passes)."""
        for group in group_by(objects, lambda o: id(o.mesh_data)):
            self.get(group[0].mesh_data).draw(prog, instance_data(group))

    def forget(self, keep=()):
        """Release GPU buffers of meshes not in ``keep`` (called when a scene is replaced)."""
        keep_ids = {id(m) for m in keep}
        for key in list(self._meshes):
            if key not in keep_ids:
                self._meshes.pop(key)[1].release()

    def vao_tables(self) -> list[dict]:
        """The vertex-array tables (id(program) -> vertex array) of every mesh: a program that is
        replaced or released takes its vertex arrays with it (``ProgramCache``)."""
        return [gm.vaos for _, gm in self._meshes.values()]

    def release(self):
        for _, gm in self._meshes.values():
            gm.release()
        self._meshes.clear()
