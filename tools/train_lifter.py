"""Train pinrecon's 2D-to-3D lifter (``pinrecon.lifter``) from the CMU clips in the shared data.

Data: the 61 CMU clips of ``cmu-iclone/`` (subjects 1, 2, 3, 5, 6, 7; iClone CC_Base skeleton,
centimetres, 60 fps, T-pose frame 0 dropped) plus the CMU clips of ``mocap/`` whose captures are
not already among them (09_01, subject 9, MotionBuilder BVH at 120 fps; 131_03, subject 131,
3dsMax BVH), read with pinrecon's BVH reader, forward kinematics in NumPy, the 12 COCO-17 body
joints in metres. ``--hold-out`` leaves whole subjects out (default 2 and 9: the shipped weights
never saw the walk 02_01 nor the run 09_01, the bench's and the tests' held-out clips).

Each training sample: a clip, a frame rate (20-50 frames/s, by taking every k-th frame), a
161-frame segment; mirrored (left/right exchanged) half the time; bones scaled (+-12 % per
limb, +-15 % hip and shoulder width); a random perspective camera (all around, 2.5-12 m,
0.2-3 m high, 5 degrees of roll, f 600-2500 px for 1920 x 1080, the person off-centre); the
faults of 2D detectors (0-4 px noise, 0-5 % outliers thrown 20-100 px with lower confidence,
0-3 % of frames with left/right exchanged, 0-10 % points missing and spans of one missing
point, sometimes no confidences at all); the camera's intrinsics given (normalised
coordinates) three times in four; with ``--spin SHARE`` that share of the segments turned
about the vertical at a steady 0.25-2 turns a second (not for the shipped weights: the model
card says why). Features: ``pinrecon.lifter.features`` (the same function inference uses) of
the 161 frames, the middle 81 kept. Target: the middle frame's joints
relative to the hips' midpoint in the camera's axes, in mean limb lengths. Model: a temporal
convolution (VideoPose3D's: kernel 3 stride 3 over 81 frames, 3 residual blocks, BatchNorm,
dropout), loss MPJPE + 0.1 x a Gaussian NLL for the per-joint spread (errors detached).

    OMP_NUM_THREADS=1 PINRECON_DATA=... nice python tools/train_lifter.py            # shipped weights
    python tools/train_lifter.py --hold-out 5 --out /tmp/lifter_no5.npz               # a bench fold

PyTorch (``pip install torch==2.13.0``, the CPU wheel) is needed here only; inference is NumPy.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from pinrecon import datasets
from pinrecon.io.bvh_format import read_bvh
from pinrecon.lifter import BODY, HALF_WINDOW, N_FEATURES, features
from pinrecon.rotations import euler_to_matrix

ROOT = Path(__file__).resolve().parents[1]
SEG = 4 * HALF_WINDOW + 1  # 161 frames: features' running median sees the whole window of each kept frame
WIN = 2 * HALF_WINDOW + 1  # 81
LEFT = [i for i, n in enumerate(BODY) if n.startswith("left_")]
RIGHT = [BODY.index("right_" + BODY[i][5:]) for i in LEFT]
FLIP = np.arange(len(BODY))
FLIP[LEFT], FLIP[RIGHT] = RIGHT, LEFT
LIMBS = [(BODY.index(f"{s}_{a}"), BODY.index(f"{s}_{b}")) for s in ("left", "right")
         for a, b in (("shoulder", "elbow"), ("elbow", "wrist"), ("hip", "knee"), ("knee", "ankle"))]

#: COCO body point -> joint, per skeleton naming (the first joint name present decides)
SKELETONS = {
    "CC_Base_L_Thigh": {"left_shoulder": "CC_Base_L_Upperarm", "right_shoulder": "CC_Base_R_Upperarm",
                        "left_elbow": "CC_Base_L_Forearm", "right_elbow": "CC_Base_R_Forearm",
                        "left_wrist": "CC_Base_L_Hand", "right_wrist": "CC_Base_R_Hand",
                        "left_hip": "CC_Base_L_Thigh", "right_hip": "CC_Base_R_Thigh",
                        "left_knee": "CC_Base_L_Calf", "right_knee": "CC_Base_R_Calf",
                        "left_ankle": "CC_Base_L_Foot", "right_ankle": "CC_Base_R_Foot"},
    "LeftUpLeg": {"left_shoulder": "LeftArm", "right_shoulder": "RightArm", "left_elbow": "LeftForeArm",
                  "right_elbow": "RightForeArm", "left_wrist": "LeftHand", "right_wrist": "RightHand",
                  "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "left_knee": "LeftLeg",
                  "right_knee": "RightLeg", "left_ankle": "LeftFoot", "right_ankle": "RightFoot"},
    "LeftKnee": {"left_shoulder": "LeftShoulder", "right_shoulder": "RightShoulder", "left_elbow": "LeftElbow",
                 "right_elbow": "RightElbow", "left_wrist": "LeftWrist", "right_wrist": "RightWrist",
                 "left_hip": "LeftHip", "right_hip": "RightHip", "left_knee": "LeftKnee",
                 "right_knee": "RightKnee", "left_ankle": "LeftAnkle", "right_ankle": "RightAnkle"},
}
#: mocap/ clips whose captures cmu-iclone/ does not already hold
MOCAP_EXTRA = {"mocap/cmu-mb_09_01.bvh": (9, 1, 0.056444), "mocap/cmu-max_131_03.bvh": (131, 0, 0.056444)}


def data_list() -> list[tuple[str, int, int, float]]:
    """(dataset name, subject, frames to skip at the start, metres per file unit) of every clip."""
    out = [(n, int(Path(n).name[:3]), 1, 0.01) for n in datasets.names("cmu-iclone/") if n.endswith(".bvh")]
    out += [(n, s, k, u) for n, (s, k, u) in MOCAP_EXTRA.items() if n in datasets.registry()]
    return out


def joints_of(name: str, skip: int, unit_m: float) -> tuple[np.ndarray, float]:
    """The clip's 12 body joints (T, 12, 3) in metres (world Y up) by forward kinematics, and its fps."""
    clip = read_bvh(datasets.fetch(name))
    names = clip.names
    mapping = next(m for key, m in SKELETONS.items() if key in names)
    want = [names.index(mapping[b]) for b in BODY]
    need = set()
    for j in want:
        while j >= 0 and j not in need:
            need.add(j)
            j = clip.joints[j].parent
    cols = clip.channel_columns()
    F = clip.n_frames
    Rg, pg = {}, {}
    for j in sorted(need):  # parents come before children in file order
        jt = clip.joints[j]
        block = clip.values[:, cols[j]]
        t = np.tile(np.asarray(jt.offset, float), (F, 1))
        axes, idx = "", []
        for k, ch in enumerate(jt.channels):
            if ch.endswith("position"):
                t[:, "XYZ".index(ch[0])] += block[:, k]
            else:
                axes += ch[0]
                idx.append(k)
        R = euler_to_matrix(axes, block[:, idx]) if axes else np.broadcast_to(np.eye(3), (F, 3, 3))
        if jt.parent < 0:
            Rg[j], pg[j] = R, t
        else:
            Rg[j] = Rg[jt.parent] @ R
            pg[j] = pg[jt.parent] + np.einsum("fij,fj->fi", Rg[jt.parent], t)
    P = np.stack([pg[j] for j in want], axis=1)[skip:] * unit_m
    return P, clip.fps


def load_clips(hold_out: set[int]):
    train, held = [], []
    for name, subj, skip, unit in data_list():
        P, fps = joints_of(name, skip, unit)
        (held if subj in hold_out else train).append({"name": name, "subject": subj, "P": P, "fps": fps})
    return train, held


def look_at(eye, target, roll):
    """(B, 3, 3) world -> camera rotations (OpenCV axes), world Y up, with a roll about the view axis."""
    z = target - eye
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    x = np.cross(-np.array([0.0, 1.0, 0.0])[None], z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=1)
    c, s = np.cos(roll), np.sin(roll)
    Rz = np.zeros_like(R)
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
    return Rz @ R


def spun(P: np.ndarray, dt: np.ndarray, rng: np.random.Generator, share: float, turns: float) -> np.ndarray:
    """``P`` (B, SEG, K, 3), a ``share`` of the samples turned about the vertical through the hips'
    midpoint at a steady rate of 0.25-``turns`` turns a second either way (``dt``: (B,) seconds
    between the samples' frames): spins and pirouettes the clips do not hold."""
    pick = np.flatnonzero(rng.random(len(P)) < share)
    if not len(pick):
        return P
    rate = 2 * np.pi * rng.uniform(0.25, turns, len(pick)) * rng.choice([-1.0, 1.0], len(pick))
    theta = rate[:, None] * dt[pick, None] * (np.arange(SEG) - SEG // 2)[None]  # (n, SEG), 0 mid-window
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    centre = P[pick][:, :, [6, 7]].mean(2, keepdims=True)
    x, z = P[pick, ..., 0] - centre[..., 0], P[pick, ..., 2] - centre[..., 2]
    P = P.copy()
    P[pick, ..., 0] = centre[..., 0] + c * x + s * z
    P[pick, ..., 2] = centre[..., 2] - s * x + c * z
    return P


def sample(clips, weights, B: int, rng: np.random.Generator, faults: bool = True,
           spin: float = 0.0, turns: float = 2.0):
    """A batch: features (B, 81, N_FEATURES) and targets (B, 12, 3) in limb lengths;
    ``spin``: the share of samples turned by :func:`spun`."""
    K = len(BODY)
    P = np.empty((B, SEG, K, 3))
    dt = np.empty(B)
    for b in range(B):
        c = clips[rng.choice(len(clips), p=weights)]
        st = max(1, round(c["fps"] / rng.uniform(20.0, 50.0)))
        T = len(c["P"])
        t0 = rng.integers(T)
        P[b] = c["P"][np.clip(t0 + st * (np.arange(SEG) - SEG // 2), 0, T - 1)]
        dt[b] = st / c["fps"]
    if spin > 0:
        P = spun(P, dt, rng, spin, turns)
    mirror = rng.random(B) < 0.5
    P[mirror] = P[mirror][:, :, FLIP] * np.array([-1.0, 1.0, 1.0])
    # bones scaled: hips and shoulders about their midpoints, torso, then each limb outwards
    hipc = P[:, :, [6, 7]].mean(2, keepdims=True)
    shc = P[:, :, [0, 1]].mean(2, keepdims=True)
    torso = rng.uniform(0.9, 1.1, (B, 1, 1, 1))
    new_shc = hipc + torso * (shc - hipc)
    Q = P.copy()
    Q[:, :, [6, 7]] = hipc + rng.uniform(0.85, 1.15, (B, 1, 1, 1)) * (P[:, :, [6, 7]] - hipc)
    Q[:, :, [0, 1]] = new_shc + rng.uniform(0.85, 1.15, (B, 1, 1, 1)) * (P[:, :, [0, 1]] - shc)
    base = rng.uniform([0.9, 0.7, 0.9, 0.9], [1.15, 1.1, 1.1, 1.1], (B, 4))  # upper arm, forearm, thigh, shank
    for k, (a, c) in enumerate([(0, 2), (2, 4), (6, 8), (8, 10)]):
        for side in (0, 1):
            f = (base[:, k] * rng.uniform(0.97, 1.03, B))[:, None, None]
            Q[:, :, c + side] = Q[:, :, a + side] + f * (P[:, :, c + side] - P[:, :, a + side])
    P = Q
    # cameras
    mid = P[:, HALF_WINDOW: HALF_WINDOW + WIN, [6, 7]].mean((1, 2))
    target = mid + rng.normal(0.0, [0.3, 0.2, 0.3], (B, 3))
    az = rng.uniform(0.0, 2 * np.pi, B)
    dist = rng.uniform(2.5, 12.0, B)
    eye = target + dist[:, None] * np.stack([np.cos(az), np.zeros(B), np.sin(az)], 1)
    eye[:, 1] = rng.uniform(0.2, 3.0, B)
    R = look_at(eye, target, np.radians(rng.normal(0.0, 5.0, B)))
    Pc = np.matmul((P - eye[:, None, None]).reshape(B, -1, 3), R.transpose(0, 2, 1)).reshape(P.shape)
    zmin = Pc[..., 2].min((1, 2))
    push = np.maximum(1.0 - zmin, 0.0)  # the camera steps back until every point is 1 m in front
    Pc[..., 2] += push[:, None, None]
    f = rng.uniform(600.0, 2500.0, B)
    cxy = np.array([960.0, 540.0])
    xy = Pc[..., :2] / Pc[..., 2:3]
    uv = f[:, None, None, None] * xy + cxy
    conf = rng.uniform(0.5, 1.0, (B, SEG, K))
    if faults:
        uv += rng.normal(0.0, 1.0, uv.shape) * rng.uniform(0.0, 4.0, (B, 1, 1, 1))
        out = rng.random((B, SEG, K)) < rng.uniform(0.0, 0.05, (B, 1, 1))
        ang = rng.uniform(0, 2 * np.pi, out.shape)
        r = rng.uniform(20.0, 100.0, out.shape) * out
        uv += np.stack([np.cos(ang), np.sin(ang)], -1) * r[..., None]
        conf = np.where(out, rng.uniform(0.1, 0.6, out.shape), conf)
        swap = rng.random((B, SEG)) < rng.uniform(0.0, 0.03, (B, 1))
        uv = np.where(swap[..., None, None], uv[:, :, FLIP], uv)
        conf = np.where(swap[..., None], conf[:, :, FLIP], conf)
        miss = rng.random((B, SEG, K)) < rng.uniform(0.0, 0.1, (B, 1, 1))
        for b in np.flatnonzero(rng.random(B) < 0.3):  # one point lost for a span
            a = rng.integers(SEG)
            miss[b, a: a + rng.integers(5, 60), rng.integers(K)] = True
        miss[rng.random(B) < 0.02] = False
        uv[miss] = np.nan
        conf[miss] = 0.0
        conf = np.where((rng.random(B) < 0.2)[:, None, None] & ~miss, 1.0, conf)
    known = rng.random(B) < 0.75
    inp = np.where(known[:, None, None, None], (uv - cxy) / f[:, None, None, None], uv)
    X = features(inp, conf, known=known)[:, HALF_WINDOW: HALF_WINDOW + WIN]
    L = np.mean([np.linalg.norm(P[:, :, a] - P[:, :, c], axis=-1).mean(1) for a, c in LIMBS], axis=0)
    Yc = Pc[:, SEG // 2]
    Y = (Yc - Yc[:, [6, 7]].mean(1, keepdims=True)) / L[:, None, None]
    return X.astype(np.float32), Y.astype(np.float32)


def build_model(H: int, drop: float):
    import torch
    from torch import nn

    class Lifter(nn.Module):
        def __init__(self):
            super().__init__()
            self.inp, self.bn = nn.Linear(3 * N_FEATURES, H), nn.BatchNorm1d(H, momentum=0.1)
            self.l1 = nn.ModuleList([nn.Linear(3 * H, H) for _ in range(3)])
            self.n1 = nn.ModuleList([nn.BatchNorm1d(H, momentum=0.1) for _ in range(3)])
            self.l2 = nn.ModuleList([nn.Linear(H, H) for _ in range(3)])
            self.n2 = nn.ModuleList([nn.BatchNorm1d(H, momentum=0.1) for _ in range(3)])
            self.out = nn.Linear(H, 4 * len(BODY))
            self.drop = nn.Dropout(drop)

        @staticmethod
        def _bn(bn, h):
            B, n, C = h.shape
            return bn(h.reshape(B * n, C)).reshape(B, n, C)

        def forward(self, x):
            B = x.shape[0]
            h = x.reshape(B, WIN // 3, 3 * N_FEATURES)
            h = self.drop(torch.relu(self._bn(self.bn, self.inp(h))))
            for k in range(3):
                n = h.shape[1]
                res = h[:, 1::3]
                y = h.reshape(B, n // 3, 3 * H)
                y = self.drop(torch.relu(self._bn(self.n1[k], self.l1[k](y))))
                y = self.drop(torch.relu(self._bn(self.n2[k], self.l2[k](y))))
                h = res + y
            return self.out(h[:, 0])

    return Lifter()


def fold(lin, bn, taps: int | None):
    """NumPy weights of Linear + eval BatchNorm: (taps, in, out) (or (in, out)) and (out,)."""
    W = lin.weight.detach().double().numpy()
    b = lin.bias.detach().double().numpy()
    if bn is not None:
        g = bn.weight.detach().double().numpy() / np.sqrt(bn.running_var.double().numpy() + bn.eps)
        W = W * g[:, None]
        b = (b - bn.running_mean.double().numpy()) * g + bn.bias.detach().double().numpy()
    W = W.T  # (in, out)
    if taps:
        W = W.reshape(taps, W.shape[0] // taps, W.shape[1])
    return W.astype(np.float32), b.astype(np.float32)


def export(model) -> dict:
    L = {}
    L["in_W"], L["in_b"] = fold(model.inp, model.bn, 3)
    for k in range(3):
        L[f"b{k}_W1"], L[f"b{k}_b1"] = fold(model.l1[k], model.n1[k], 3)
        L[f"b{k}_W2"], L[f"b{k}_b2"] = fold(model.l2[k], model.n2[k], None)
    L["out_W"], L["out_b"] = fold(model.out, None, None)
    return L


def load_init(model, path: str) -> dict:
    """Start ``model`` from a weights file this tool wrote (BatchNorm folded in): each Linear
    takes the folded weights and each BatchNorm becomes the identity, held in eval mode while
    training goes on (:func:`freeze_norms`); returns the file's meta (its provenance)."""
    import torch

    with np.load(path, allow_pickle=False) as z:
        L = {k: np.asarray(z[k], np.float32) for k in z.files if not k.startswith(("meta", "fixture_"))}
        meta = json.loads(str(z["meta"]))

    def put(lin, bn, W, b):
        W = W.reshape(-1, W.shape[-1])  # (taps * in, out)
        with torch.no_grad():
            lin.weight.copy_(torch.from_numpy(W.T.copy()))
            lin.bias.copy_(torch.from_numpy(b))
            if bn is not None:
                bn.weight.fill_(1.0)
                bn.bias.zero_()
                bn.running_mean.zero_()
                bn.running_var.fill_(1.0 - bn.eps)

    put(model.inp, model.bn, L["in_W"], L["in_b"])
    for k in range(3):
        put(model.l1[k], model.n1[k], L[f"b{k}_W1"], L[f"b{k}_b1"])
        put(model.l2[k], model.n2[k], L[f"b{k}_W2"], L[f"b{k}_b2"])
    put(model.out, None, L["out_W"], L["out_b"])
    return meta


def freeze_norms(model) -> None:
    """BatchNorm layers in eval mode (their running statistics held) while the rest trains."""
    for m in [model.bn, *model.n1, *model.n2]:
        m.eval()


def loss_terms(out, Y):
    import torch

    K = len(BODY)
    mu = out[:, : 3 * K].reshape(-1, K, 3)
    log_s = out[:, 3 * K:].clamp(-6.0, 3.0)
    d = mu - Y
    mpjpe = d.norm(dim=-1).mean()
    nll = (0.5 * (d.detach() ** 2).sum(-1) * torch.exp(-2 * log_s) + 3 * log_s).mean()
    return mpjpe, nll


def sha256(path) -> str:
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def git_commit() -> str:
    try:
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True, check=False).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, check=False).stdout.strip()
        return head + ("+dirty" if dirty else "")
    except OSError:
        return "unknown"


def fixture(model, rng):
    """Features of a short synthetic sequence and the trained network's outputs on them (torch,
    float64, edges padded by repeating the end frames): what NumPy inference must reproduce."""
    import torch

    X, _ = sample(FIXTURE_CLIPS[:1], np.array([1.0]), 1, rng)
    seq = np.concatenate([X[0], X[0][::-1][1:40]])  # 120 frames of real features
    T = len(seq)
    idx = np.clip(np.arange(T)[:, None] + np.arange(WIN)[None] - HALF_WINDOW, 0, T - 1)
    m64 = build_model(model.inp.out_features, 0.0).double()
    m64.load_state_dict({k: v.double() if v.is_floating_point() else v for k, v in model.state_dict().items()})
    m64.eval()
    # the exported weights are float32: the reference uses the same rounded, folded weights' source
    with torch.no_grad():
        for p in m64.parameters():
            p.copy_(p.float().double())
        Yf = m64(torch.from_numpy(seq.astype(np.float32).astype(np.float64)[idx])).numpy()
    return seq.astype(np.float32), Yf


FIXTURE_CLIPS: list = []


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hold-out", type=int, nargs="*", default=[2, 9],
                    help="subjects left out of training (default 2 and 9)")
    ap.add_argument("--out", default=str(ROOT / "models" / "lifter" / "lifter.npz"))
    ap.add_argument("--steps", type=int, default=1600)
    ap.add_argument("--batch", type=int, default=128)
    ap.add_argument("--hidden", type=int, default=256)
    ap.add_argument("--dropout", type=float, default=0.15)
    ap.add_argument("--lr", type=float, default=2e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--spin", type=float, default=0.0,
                    help="share of training samples turned about the vertical (spins; default 0)")
    ap.add_argument("--turns", type=float, default=2.0, help="the spins' fastest rate, turns a second")
    ap.add_argument("--init", help="go on training from this weights file (the same --hold-out: checked)")
    a = ap.parse_args(argv)
    import torch

    commit = git_commit()  # the tree the run started from
    torch.manual_seed(a.seed)
    torch.set_num_threads(a.threads)
    rng = np.random.default_rng(a.seed)
    t0 = time.time()
    hold = set(a.hold_out)
    train, held = load_clips(hold)
    frames = np.array([len(c["P"]) for c in train], float)
    w = frames / frames.sum()
    print(f"{len(train)} training clips ({int(frames.sum())} frames), {len(held)} held out "
          f"(subjects {sorted(hold)}), loaded in {time.time() - t0:.0f} s", flush=True)
    vrng = np.random.default_rng(1000 + a.seed)
    val = [sample(held, np.full(len(held), 1 / len(held)), 256, vrng) for _ in range(2)] if held else []
    model = build_model(a.hidden, a.dropout)
    init = None
    if a.init:
        init = load_init(model, a.init)
        if sorted(init.get("held_out_subjects", [])) != sorted(hold):
            raise SystemExit(f"--init {a.init} held out subjects {init.get('held_out_subjects')}, not {sorted(hold)}")
    opt = torch.optim.AdamW(model.parameters(), lr=a.lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=a.lr, total_steps=a.steps, pct_start=0.05)
    t1 = time.time()
    log = []
    for step in range(a.steps):
        model.train()
        if init is not None:
            freeze_norms(model)
        X, Y = sample(train, w, a.batch, rng, spin=a.spin, turns=a.turns)
        mpjpe, nll = loss_terms(model(torch.from_numpy(X)), torch.from_numpy(Y))
        loss = mpjpe + 0.1 * nll
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 5.0)
        opt.step()
        sched.step()
        if step % 250 == 0 or step == a.steps - 1:
            model.eval()
            with torch.no_grad():
                vm = [float(loss_terms(model(torch.from_numpy(vx)), torch.from_numpy(vy))[0]) for vx, vy in val]
            v = float(np.mean(vm)) if vm else float("nan")
            log.append({"step": step, "train_mpjpe": mpjpe.item(), "val_mpjpe": v})
            print(f"step {step:5d}  train MPJPE {mpjpe.item():.3f}  NLL {nll.item():.3f}  held-out MPJPE {v:.3f} "
                  f"(limb lengths)  {time.time() - t1:.0f} s", flush=True)
    model.eval()
    layers = export(model)
    FIXTURE_CLIPS[:] = held or train
    fx, fy = fixture(model, np.random.default_rng(7))
    reg = datasets.registry()
    meta = {
        "what": "pinrecon 2D-to-3D lifter (tools/train_lifter.py)",
        "commit": commit,
        "versions": {"python": platform.python_version(), "numpy": np.__version__, "torch": torch.__version__},
        "seed": a.seed, "held_out_subjects": sorted(hold),
        "data": [{"name": c["name"], "subject": c["subject"], "sha256": reg[c["name"]].sha256, "frames": len(c["P"])}
                 for c in train],
        "held_out_clips": [c["name"] for c in held],
        "init": None if init is None else {"file": Path(a.init).name, "sha256": sha256(a.init),
                                           "commit": init.get("commit"), "steps": init.get("args", {}).get("steps"),
                                           "train_seconds": init.get("train_seconds"), "seed": init.get("seed"),
                                           "init": init.get("init")},
        "args": vars(a), "train_seconds": round(time.time() - t1, 1), "log": log,
        "body": list(BODY), "half_window": HALF_WINDOW,
        "command": "python tools/train_lifter.py " + " ".join(sys.argv[1:] if argv is None else argv),
    }
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(a.out, meta=json.dumps(meta), fixture_X=fx, fixture_Y=fy, **layers)
    print(f"wrote {a.out} ({Path(a.out).stat().st_size / 1e6:.1f} MB) in {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
