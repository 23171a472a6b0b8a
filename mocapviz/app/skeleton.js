// What the dashboard's two skeleton components share, run in the browser: the bones coloured by side (the colours
// sent by the server, mocapviz.viz.palette.SIDES), the camera (a perspective projection looking at a scene box), a pose's joints on screen and its bones drawn far to near.
// Not a module of its own: player.py's component_code() puts this file before the component's own code (player.js,
// gallery.js), so both draw a skeleton the same way and nothing is fetched at run time.

const FOV = (30 * Math.PI) / 180;
const HOME = { azimuth: 30, elevation: 18, zoom: 1 };

function arrayBuffer(value) {
  if (value == null) {
    return new ArrayBuffer(0);
  }
  if (value instanceof ArrayBuffer) {
    return value;
  }
  if (ArrayBuffer.isView(value)) {
    return value.buffer.slice(value.byteOffset, value.byteOffset + value.byteLength);
  }
  if (typeof value === "string") {  // base64, as a fallback
    const text = atob(value);
    const out = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) {
      out[i] = text.charCodeAt(i);
    }
    return out.buffer;
  }
  throw new Error(`mocapviz: cannot read skeleton data of type ${typeof value}`);
}

function element(tag, className, text) {
  const el = document.createElement(tag);
  if (className) {
    el.className = className;
  }
  if (text != null) {
    el.textContent = text;
  }
  return el;
}

// ------------------------------------------------------------------------------------------------------- camera
// a camera looking at the middle of `bounds` ([lo, hi] corners, cm) from azimuth / elevation (degrees), the whole box
// in view at zoom 1, drawn into the rectangle (left, top, width, height) of the canvas
function makeCamera(bounds, azimuthDeg, elevationDeg, zoom, width, height, left, top = 0) {
  const [lo, hi] = bounds;
  const target = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2];
  const radius = Math.max(1, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
  const distance = radius / Math.sin(FOV / 2);
  const a = (azimuthDeg * Math.PI) / 180;
  const e = (elevationDeg * Math.PI) / 180;
  const eye = [target[0] + distance * Math.cos(e) * Math.sin(a), target[1] + distance * Math.sin(e),
               target[2] + distance * Math.cos(e) * Math.cos(a)];
  const f = [target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]];
  const fn = Math.hypot(f[0], f[1], f[2]);
  f[0] /= fn; f[1] /= fn; f[2] /= fn;
  const r = [-f[2], 0, f[0]];  // f x (0, 1, 0): right-handed, like OpenGL's lookAt
  const rn = Math.hypot(r[0], r[2]) || 1;
  r[0] /= rn; r[2] /= rn;
  const u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]];
  const focal = (zoom * 0.5 * Math.min(width, height)) / Math.tan(FOV / 2);
  return { eye, f, r, u, focal, cx: left + width / 2, cy: top + height / 2, near: distance * 0.02 };
}

// camera coordinates (x right, y up, z depth) of point i of a flat xyz array
function toCamera(cam, xyz, i, out) {
  const dx = xyz[i] - cam.eye[0];
  const dy = xyz[i + 1] - cam.eye[1];
  const dz = xyz[i + 2] - cam.eye[2];
  out[0] = dx * cam.r[0] + dy * cam.r[1] + dz * cam.r[2];
  out[1] = dx * cam.u[0] + dy * cam.u[1] + dz * cam.u[2];
  out[2] = dx * cam.f[0] + dy * cam.f[1] + dz * cam.f[2];
}

// ------------------------------------------------------------------------------------------------------- poses
// the nJoints joints of the pose at xyz[base...] on screen: [x, y, depth] each
function projectPose(cam, xyz, base, nJoints) {
  const p = [0, 0, 0];
  const screen = new Array(nJoints);
  for (let k = 0; k < nJoints; k++) {
    toCamera(cam, xyz, base + 3 * k, p);
    const z = Math.max(p[2], cam.near);
    screen[k] = [cam.cx + (cam.focal * p[0]) / z, cam.cy - (cam.focal * p[1]) / z, z];
  }
  return screen;
}

// the bones of a projected pose into `out` as [depth, x0, y0, x1, y1, colour, alpha, line width]; `colours`: side
// letter -> CSS colour (mocapviz.viz.palette.SIDES)
function poseBones(cam, screen, parents, sides, colours, alpha, out) {
  for (let k = 0; k < screen.length; k++) {
    const parent = parents[k];
    if (parent < 0) {
      continue;
    }
    const s = screen[k];
    const t = screen[parent];
    const depth = (s[2] + t[2]) / 2;
    out.push([depth, t[0], t[1], s[0], s[1], colours[sides[k]] || colours.c, alpha,
              Math.max(2, Math.min(6, (cam.focal * 4) / depth))]);
  }
}

// the bones `segs` (of poseBones) far to near, then the joints of `poses` ([screen, alpha] each) as dots
function drawPoses(ctx, segs, poses, radius) {
  segs.sort((s, t) => t[0] - s[0]);
  ctx.lineCap = "round";
  for (const [, x0, y0, x1, y1, colour, alpha, w] of segs) {
    ctx.globalAlpha = alpha;
    ctx.strokeStyle = colour;
    ctx.lineWidth = w;
    ctx.beginPath();
    ctx.moveTo(x0, y0);
    ctx.lineTo(x1, y1);
    ctx.stroke();
  }
  for (const [screen, alpha] of poses) {
    ctx.globalAlpha = alpha;
    ctx.fillStyle = "#222";
    for (const [x, y] of screen) {
      ctx.beginPath();
      ctx.arc(x, y, radius, 0, 2 * Math.PI);
      ctx.fill();
    }
  }
  ctx.globalAlpha = 1;
}
