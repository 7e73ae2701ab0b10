"""A self-contained HTML player of a result: the 3D motion, playable offline.

One file, no network, no library: the keypoints (millimetres, as integers) and the
skeleton's edges are embedded as JSON and drawn by about 60 lines of inline JavaScript on a
2D canvas with an orthographic view that the mouse orbits (drag), zooms (wheel) and the
timeline plays and scrubs. The floor grid lies under the lowest keypoint; the camera that
saw the tracks is drawn as a small frustum. ``pinrecon export result.npz --html out.html``.
"""

from __future__ import annotations

import html
import json
import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from .edits import skeleton_edges

__all__ = ["export_html", "html_player"]


def _scene(result, keyframe_frames=None) -> dict:
    fig = result.figure
    P = np.asarray(result.keypoints3d, float)
    if P.ndim != 3 or P.shape[-1] != 3 or not len(P):
        raise InputError(f"expected keypoints3d of shape (T, K, 3), got {P.shape}", field="keypoints3d")
    names = list(fig.keypoint_names) if fig is not None else [f"k{i}" for i in range(P.shape[1])]
    edges = [[int(a), int(b)] for a, b in skeleton_edges(fig)] if fig is not None else []
    cam = result.camera
    if isinstance(cam, (list, tuple)):  # several cameras: draw the first
        cam = cam[0] if cam else None
    if cam is not None and not hasattr(cam, "R"):
        cam = None
    up = np.array([0.0, 1.0, 0.0])
    cam_d = None
    if cam is not None:
        R = np.asarray(cam.R, float)
        up = -R[1]
        if getattr(cam, "model", "") == "perspective":
            centre = -R.T @ np.asarray(cam.t, float)
            cam_d = {"pos": centre.tolist(), "R": R.tolist(), "ortho": False}
        else:
            mid = np.nanmean(P.reshape(-1, 3), axis=0)
            cam_d = {"pos": (mid - 3.0 * R[2]).tolist(), "R": R.tolist(), "ortho": True}
    finite = np.isfinite(P)
    P_mm = np.where(finite, np.round(P * 1000.0), 0).astype(np.int64)
    err = np.asarray(getattr(result, "reprojection_error_px", np.full(len(P), np.nan)), float)
    return {
        "fps": float(result.fps),
        "T": int(P.shape[0]),
        "K": int(P.shape[1]),
        "names": names,
        "edges": edges,
        "P": P_mm.ravel().tolist(),
        "up": up.tolist(),
        "floor": float(np.nanmin(P.reshape(-1, 3) @ up)),
        "camera": cam_d,
        "err": [None if not np.isfinite(e) else round(float(e), 3) for e in err],
        "keyframes": sorted({int(f) for f in (() if keyframe_frames is None else keyframe_frames)}),
    }


_TEMPLATE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>
body{margin:0;font:14px system-ui,sans-serif;background:#f4f4f2;color:#222}
#bar{display:flex;gap:8px;align-items:center;padding:6px 10px;background:#fff;border-bottom:1px solid #ccc}
#view{display:block;width:100vw;height:calc(100vh - 120px);cursor:grab;background:#fbfbfa}
#slider{flex:1}#tl{display:block;width:100vw;height:70px;background:#fff;border-top:1px solid #ccc}
button{font:inherit;padding:2px 10px}
</style></head><body>
<div id="bar"><b>__TITLE__</b><button id="play">Play</button>
<input id="slider" type="range" min="0" value="0" step="1"><span id="label"></span>
<label><input id="follow" type="checkbox" checked> follow</label></div>
<canvas id="view"></canvas><canvas id="tl"></canvas>
<script id="data" type="application/json">__DATA__</script>
<script>
"use strict";
const D=JSON.parse(document.getElementById("data").textContent);
const T=D.T,K=D.K,P=D.P;const view=document.getElementById("view"),tl=document.getElementById("tl");
const slider=document.getElementById("slider"),label=document.getElementById("label"),play=document.getElementById("play");
slider.max=T-1;let frame=0,playing=false,yaw=0.6,pitch=0.35,zoom=1,last=0;
function norm(v){const n=Math.hypot(v[0],v[1],v[2])||1;return[v[0]/n,v[1]/n,v[2]/n]}
function cross(a,b){return[a[1]*b[2]-a[2]*b[1],a[2]*b[0]-a[0]*b[2],a[0]*b[1]-a[1]*b[0]]}
function dot(a,b){return a[0]*b[0]+a[1]*b[1]+a[2]*b[2]}
const up=norm(D.up);let e1=norm(cross(up,Math.abs(up[0])<0.9?[1,0,0]:[0,0,1]));const e2=cross(e1,up);
function pt(t,k){const i=(t*K+k)*3;return[P[i]/1000,P[i+1]/1000,P[i+2]/1000]}
let span=0.5;
(function(){let lo=[1e9,1e9,1e9],hi=[-1e9,-1e9,-1e9];for(let t=0;t<T;t++)for(let k=0;k<K;k++){const p=pt(t,k);
for(let a=0;a<3;a++){lo[a]=Math.min(lo[a],p[a]);hi[a]=Math.max(hi[a],p[a])}}
const c=[0,0,0];for(let k=0;k<K;k++){const p=pt(0,k);for(let a=0;a<3;a++)c[a]+=p[a]/K}
let h=0;for(let k=0;k<K;k++)h=Math.max(h,Math.abs(dot(pt(0,k),up)-dot(c,up)));span=Math.max(0.5,2.4*h)})();
function basis(){const cy=Math.cos(yaw),sy=Math.sin(yaw),cp=Math.cos(pitch),sp=Math.sin(pitch);
const fwd=[0,1,2].map(a=>cp*(cy*e1[a]+sy*e2[a])-sp*up[a]);const right=norm(cross(fwd,up));const vup=cross(right,fwd);return[right,vup,fwd]}
function centre(t){const c=[0,0,0];for(let k=0;k<K;k++){const p=pt(t,k);for(let a=0;a<3;a++)c[a]+=p[a]/K}return c}
let fixedC=centre(0);
function draw(){const W=view.clientWidth,H=view.clientHeight;if(view.width!==W||view.height!==H){view.width=W;view.height=H}
const g=view.getContext("2d");g.clearRect(0,0,W,H);const [r,u]=basis();
const c=document.getElementById("follow").checked?centre(frame):fixedC;const s=zoom*H/span;
const pr=p=>{const d=[p[0]-c[0],p[1]-c[1],p[2]-c[2]];return[W/2+s*dot(d,r),H/2-s*dot(d,u)]};
const fl=D.floor,cu=dot(c,up),base=[0,1,2].map(a=>c[a]+(fl-cu)*up[a]);g.strokeStyle="#d6d6d0";g.lineWidth=1;
const step=0.5,n=12;const o1=Math.round(dot(base,e1)/step)*step-dot(base,e1),o2=Math.round(dot(base,e2)/step)*step-dot(base,e2);
for(let i=-n;i<=n;i++){for(const [a,b] of [[e1,e2],[e2,e1]]){const off=(a===e1?o1:o2)+i*step;
const p0=[0,1,2].map(j=>base[j]+off*a[j]-n*step*b[j]),p1=[0,1,2].map(j=>base[j]+off*a[j]+n*step*b[j]);
const q0=pr(p0),q1=pr(p1);g.beginPath();g.moveTo(q0[0],q0[1]);g.lineTo(q1[0],q1[1]);g.stroke()}}
if(D.camera){const R=D.camera.R,o=D.camera.pos,L=0.3;const cx=[R[0][0],R[0][1],R[0][2]],cy_=[R[1][0],R[1][1],R[1][2]],cz=[R[2][0],R[2][1],R[2][2]];
const cs=[[-1,-1],[1,-1],[1,1],[-1,1]].map(([a,b])=>[0,1,2].map(j=>o[j]+L*(cz[j]+0.6*a*cx[j]+0.45*b*cy_[j])));
g.strokeStyle="#555";g.lineWidth=1.5;const po=pr(o);for(const q of cs){const pq=pr(q);g.beginPath();g.moveTo(po[0],po[1]);g.lineTo(pq[0],pq[1]);g.stroke()}
g.beginPath();cs.forEach((q,i)=>{const pq=pr(q);i?g.lineTo(pq[0],pq[1]):g.moveTo(pq[0],pq[1])});g.closePath();g.stroke()}
g.lineWidth=4;g.lineCap="round";for(const [a,b] of D.edges){const pa=pr(pt(frame,a)),pb=pr(pt(frame,b));
const nm=D.names[b];g.strokeStyle=nm.startsWith("left")||nm.startsWith("Left")?"#1f6fd1":nm.startsWith("right")||nm.startsWith("Right")?"#d1431f":"#333";
g.beginPath();g.moveTo(pa[0],pa[1]);g.lineTo(pb[0],pb[1]);g.stroke()}
g.fillStyle="#111";for(let k=0;k<K;k++){const q=pr(pt(frame,k));g.beginPath();g.arc(q[0],q[1],3,0,7);g.fill()}
drawTimeline();label.textContent="frame "+frame+" / "+(T-1)+"  t = "+(frame/D.fps).toFixed(2)+" s"}
function drawTimeline(){const W=tl.clientWidth,H=tl.clientHeight;if(tl.width!==W||tl.height!==H){tl.width=W;tl.height=H}
const g=tl.getContext("2d");g.clearRect(0,0,W,H);const x=t=>8+(W-16)*t/Math.max(1,T-1);
const e=D.err.filter(v=>v!==null);const m=e.length?Math.max(...e)||1:1;g.strokeStyle="#888";g.beginPath();let on=false;
D.err.forEach((v,t)=>{if(v===null){on=false;return}const y=H-8-(H-24)*v/m;on?g.lineTo(x(t),y):g.moveTo(x(t),y);on=true});g.stroke();
g.fillStyle="#e0a000";for(const f of D.keyframes){g.beginPath();g.moveTo(x(f),4);g.lineTo(x(f)-5,13);g.lineTo(x(f)+5,13);g.fill()}
g.strokeStyle="#c00";g.lineWidth=2;g.beginPath();g.moveTo(x(frame),0);g.lineTo(x(frame),H);g.stroke();g.lineWidth=1;
g.fillStyle="#555";g.fillText(e.length?"reprojection error (max "+m.toFixed(1)+" px)":"",12,H-2)}
function setFrame(f){frame=Math.max(0,Math.min(T-1,f|0));slider.value=frame;draw()}
slider.oninput=()=>setFrame(+slider.value);
play.onclick=()=>{playing=!playing;play.textContent=playing?"Pause":"Play";last=performance.now();if(playing)requestAnimationFrame(tick)};
let acc=0;function tick(now){if(!playing)return;acc+=(now-last)/1000*D.fps;last=now;if(acc>=1){const n=Math.floor(acc);acc-=n;setFrame((frame+n)%T)}requestAnimationFrame(tick)}
let drag=null;view.onpointerdown=e=>{drag=[e.clientX,e.clientY];view.setPointerCapture(e.pointerId)};
view.onpointermove=e=>{if(!drag)return;yaw+=(e.clientX-drag[0])*0.01;pitch=Math.max(-1.5,Math.min(1.5,pitch+(e.clientY-drag[1])*0.01));drag=[e.clientX,e.clientY];draw()};
view.onpointerup=()=>{drag=null};view.onwheel=e=>{e.preventDefault();zoom*=Math.exp(-e.deltaY*0.001);draw()};
tl.onpointerdown=e=>{const r=tl.getBoundingClientRect();setFrame(Math.round((e.clientX-r.left-8)/(r.width-16)*(T-1)))};
document.onkeydown=e=>{if(e.key===" "){e.preventDefault();play.click()}else if(e.key==="ArrowRight")setFrame(frame+1);else if(e.key==="ArrowLeft")setFrame(frame-1)};
window.onresize=draw;draw();
</script></body></html>
"""


def html_player(result, *, title: str | None = None, keyframe_frames=None) -> str:
    """The HTML text of a self-contained player of ``result`` (a :class:`pinrecon.Result`)."""
    data = json.dumps(_scene(result, keyframe_frames), separators=(",", ":"))
    data = data.replace("</", "<\\/")  # never close the script element early
    name = title or (f"pinrecon: {result.figure.name}" if result.figure is not None else "pinrecon")
    return _TEMPLATE.replace("__TITLE__", html.escape(name)).replace("__DATA__", data)


def export_html(result, path: str | os.PathLike, *, title: str | None = None, keyframe_frames=None) -> Path:
    """Write the player of ``result`` (a Result or a result NPZ path) to ``path``, atomically."""
    from .. import load_result
    from ..io.atomic import atomic_write_text

    if isinstance(result, (str, os.PathLike)):
        result = load_result(result)
    path = Path(path)
    atomic_write_text(path, html_player(result, title=title, keyframe_frames=keyframe_frames))
    return path
