// The dashboard's skeleton player, run in the browser (a Panel JSComponent: see player.py).
//
// The clips arrive once (model.positions: float32 (sum T_i, J, 3) cm, y up; model.alignment: int32 (S, n_clips)
// frame per step; model.meta: lengths, titles, fps, parents, sides, side_colours, bounds) and are animated here with
// requestAnimationFrame on a Canvas 2D: a perspective projection of the bones (line segments), coloured by side, over
// a floor grid. Drag orbits the camera, the wheel zooms, a double click resets the view. The shown step goes back to
// Python (model.step) when paused or scrubbed, and at most every SYNC_MS during playback.
//
// For tests the canvas carries data-drawn (frames drawn so far), data-step (the shown step), data-frames (the frame
// of each clip, comma separated) and data-playing, updated on every draw, and data-loads (clips received so far) and
// data-clips (their number).

const SPEEDS = [0.25, 0.5, 1, 2];
const SYNC_MS = 250;
const SCRUB_SYNC_MS = 120;

function button(className, text, title) {
  const b = element("button", className, text);
  b.type = "button";
  b.title = title;
  return b;
}

// 14 px icons (the fonts of a headless browser may lack the media-control glyphs)
const ICONS = {
  previous: "<rect x='2' y='2' width='2' height='10'/><path d='M12 2 L5 7 L12 12 Z'/>",
  play: "<path d='M3 2 L12 7 L3 12 Z'/>",
  pause: "<rect x='3' y='2' width='3' height='10'/><rect x='8' y='2' width='3' height='10'/>",
  next: "<path d='M2 2 L9 7 L2 12 Z'/><rect x='10' y='2' width='2' height='10'/>",
};

function icon(b, name) {
  b.innerHTML = `<svg width="14" height="14" viewBox="0 0 14 14" fill="currentColor">${ICONS[name]}</svg>`;
}

// ------------------------------------------------------------------------------------------------------- render
export function render({ model, el }) {
  const root = element("div", "mvp");
  const canvas = element("canvas", "mv-player-canvas");
  canvas.tabIndex = 0;
  const controls = element("div", "mvp-controls");
  const previous = button("previous", null, "previous step");
  const play = button("play", null, "play / pause");
  const next = button("next", null, "next step");
  icon(previous, "previous");
  icon(play, "play");
  icon(next, "next");
  const slider = element("input", "mv-player-slider");
  slider.type = "range";
  slider.min = "0";
  slider.step = "1";
  const speeds = element("span", "mvp-speeds");
  const speedButtons = SPEEDS.map((s) => {
    const b = button("speed", `${s}×`, `play at ${s}× the clip's rate`);
    b.dataset.speed = String(s);
    speeds.append(b);
    return b;
  });
  const layout = button("layout", "overlay", "show the clips overlaid / side by side");
  const home = button("home", "⟲", "reset the camera (or double-click the view)");
  controls.append(previous, play, next, slider, speeds, layout, home);
  const caption = element("div", "mv-player-caption");
  const captionText = element("p", null, "");
  caption.append(captionText);
  root.append(canvas, controls, caption);
  el.append(root);

  const ctx = canvas.getContext("2d");
  const st = {
    clips: [], lengths: [], titles: [], parents: [], sides: [], sideColours: { c: "#3c3c3c" },
    bounds: [[-100, 0, -100], [100, 200, 100]],
    fps: 30, nJoints: 0, align: new Int32Array(0), nSteps: 0, step: 0, pos: 0, playing: false,
    overlay: false, azimuth: HOME.azimuth, elevation: HOME.elevation, zoom: HOME.zoom,
    drawn: 0, loads: 0, lastTime: null, lastSync: 0, sent: null, scrubTimer: null, frameRequest: null, removed: false,
  };
  const dpr = Math.max(1, window.devicePixelRatio || 1);
  let width = 0;
  let height = 0;

  function resize() {
    const size = model.view_size || [520, 380];
    width = size[0];
    height = size[1];
    canvas.style.width = `${width}px`;
    canvas.style.height = `${height}px`;
    canvas.width = Math.round(width * dpr);
    canvas.height = Math.round(height * dpr);
    slider.style.width = `${Math.max(80, width - 330)}px`;
  }

  function load() {
    const meta = model.meta || {};
    const nJoints = meta.n_joints || 0;
    const data = new Float32Array(arrayBuffer(model.positions));
    const lengths = meta.lengths || [];
    st.clips = [];
    let offset = 0;
    for (const n of lengths) {
      st.clips.push(data.subarray(offset, offset + n * nJoints * 3));
      offset += n * nJoints * 3;
    }
    st.lengths = lengths;
    st.nJoints = nJoints;
    st.titles = meta.titles || [];
    st.parents = meta.parents || [];
    st.sides = meta.sides || [];
    st.sideColours = meta.side_colours || { c: "#3c3c3c" };  // mocapviz.viz.palette.SIDES
    st.bounds = meta.bounds || st.bounds;
    st.fps = meta.fps || 30;
    st.align = new Int32Array(arrayBuffer(model.alignment));
    st.nSteps = lengths.length ? Math.floor(st.align.length / lengths.length) : 0;
    if (st.scrubTimer != null) {
      clearTimeout(st.scrubTimer);
      st.scrubTimer = null;
    }
    st.step = Math.min(Math.max(0, model.step | 0), Math.max(0, st.nSteps - 1));
    st.pos = st.step;
    st.sent = model.step;
    slider.max = String(Math.max(0, st.nSteps - 1));
    slider.value = String(st.step);
    layout.style.display = lengths.length > 1 ? "" : "none";
    st.loads += 1;
    canvas.dataset.loads = String(st.loads);
    canvas.dataset.clips = String(lengths.length);
    requestDraw();
  }

  function frameOf(clip, step) {
    return st.align[step * st.lengths.length + clip];
  }

  function frames() {
    return st.lengths.map((_, j) => frameOf(j, st.step));
  }

  // ---------------------------------------------------------------------------------------------- drawing
  function drawGrid(cam) {
    const [lo, hi] = st.bounds;
    const spacing = 50;
    const x0 = Math.floor(lo[0] / spacing) * spacing;
    const x1 = Math.ceil(hi[0] / spacing) * spacing;
    const z0 = Math.floor(lo[2] / spacing) * spacing;
    const z1 = Math.ceil(hi[2] / spacing) * spacing;
    ctx.strokeStyle = "#d0d0d0";
    ctx.lineWidth = 1;
    ctx.beginPath();
    for (let x = x0; x <= x1 + 1e-6; x += spacing) {
      segment(cam, [x, 0, z0, x, 0, z1]);
    }
    for (let z = z0; z <= z1 + 1e-6; z += spacing) {
      segment(cam, [x0, 0, z, x1, 0, z]);
    }
    ctx.stroke();
  }

  const a = [0, 0, 0];
  const b = [0, 0, 0];

  // a world segment into the current path, clipped at the near plane
  function segment(cam, xyz) {
    toCamera(cam, xyz, 0, a);
    toCamera(cam, xyz, 3, b);
    if (a[2] < cam.near && b[2] < cam.near) {
      return;
    }
    if (a[2] < cam.near || b[2] < cam.near) {
      const [p, q] = a[2] < cam.near ? [a, b] : [b, a];
      const t = (cam.near - p[2]) / (q[2] - p[2]);
      p[0] += t * (q[0] - p[0]);
      p[1] += t * (q[1] - p[1]);
      p[2] = cam.near;
    }
    ctx.moveTo(cam.cx + (cam.focal * a[0]) / a[2], cam.cy - (cam.focal * a[1]) / a[2]);
    ctx.lineTo(cam.cx + (cam.focal * b[0]) / b[2], cam.cy - (cam.focal * b[1]) / b[2]);
  }

  // the bones of clip j at its frame into `out` (see poseBones); its joints on screen
  function bones(cam, j, alpha, out) {
    const screen = projectPose(cam, st.clips[j], frameOf(j, st.step) * st.nJoints * 3, st.nJoints);
    poseBones(cam, screen, st.parents, st.sides, st.sideColours, alpha, out);
    return screen;
  }

  function drawSkeletons(cam, members) {
    const segs = [];
    const joints = [];
    for (const j of members) {
      const alpha = st.overlay && j > 0 ? 0.45 : 1;
      joints.push([bones(cam, j, alpha, segs), alpha]);
    }
    drawPoses(ctx, segs, joints, 2.2);
  }

  function draw() {
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.fillStyle = "#ffffff";
    ctx.fillRect(0, 0, width, height);
    const n = st.clips.length;
    if (n && st.nSteps) {
      const views = st.overlay || n === 1 ? [[...Array(n).keys()]] : [...Array(n).keys()].map((j) => [j]);
      const w = width / views.length;
      const shown = frames();
      views.forEach((members, v) => {
        const cam = makeCamera(st.bounds, st.azimuth, st.elevation, st.zoom, w, height, v * w);
        ctx.save();
        ctx.beginPath();
        ctx.rect(v * w, 0, w, height);
        ctx.clip();
        drawGrid(cam);
        drawSkeletons(cam, members);
        ctx.font = "12px sans-serif";
        ctx.textBaseline = "top";
        members.forEach((j, line) => {
          ctx.globalAlpha = st.overlay && j > 0 ? 0.6 : 1;
          ctx.fillStyle = "#000";
          ctx.fillText(`${st.titles[j] ?? `clip ${j + 1}`}  frame ${shown[j]}`, v * w + 8, 6 + 16 * line);
        });
        ctx.globalAlpha = 1;
        ctx.restore();
        if (v > 0) {
          ctx.strokeStyle = "#bbbbbb";
          ctx.lineWidth = 1;
          ctx.beginPath();
          ctx.moveTo(v * w + 0.5, 0);
          ctx.lineTo(v * w + 0.5, height);
          ctx.stroke();
        }
      });
      canvas.dataset.frames = shown.join(",");
    }
    st.drawn += 1;
    canvas.dataset.drawn = String(st.drawn);
    canvas.dataset.step = String(st.step);
    canvas.dataset.playing = st.playing ? "1" : "0";
    const speed = model.speed || 1;  // the playing time at the lit speed (the Python caption says the same)
    const seconds = st.nSteps / st.fps / speed;
    captionText.textContent = `step ${st.step + 1} of ${st.nSteps} · ${seconds.toFixed(2)} s at ${speed}×`;
    slider.value = String(st.step);
  }

  // ---------------------------------------------------------------------------------------------- animation
  function requestDraw() {
    if (st.frameRequest == null && !st.removed) {
      st.frameRequest = requestAnimationFrame(tick);
    }
  }

  function tick(time) {
    st.frameRequest = null;
    if (st.removed || !root.isConnected) {  // removed, or replaced by a new render: after_render asks again
      return;
    }
    if (st.playing && st.nSteps > 0) {
      if (st.lastTime != null) {
        const dt = Math.min(time - st.lastTime, 250) / 1000;  // a stalled tab does not jump ahead
        st.pos = (st.pos + dt * st.fps * (model.speed || 1)) % st.nSteps;
        st.step = Math.floor(st.pos);
      }
      st.lastTime = time;
      sync(false);
    }
    draw();
    if (st.playing) {
      requestDraw();
    }
  }

  // tell Python the shown step: at once (force) or at most every SYNC_MS
  function sync(force) {
    const now = performance.now();
    if (st.step === st.sent || (!force && now - st.lastSync < SYNC_MS)) {
      return;
    }
    st.lastSync = now;
    st.sent = st.step;
    model.step = st.step;
  }

  function setPlaying(playing) {
    st.playing = playing && st.nSteps > 1;
    st.lastTime = null;
    icon(play, st.playing ? "pause" : "play");
    play.classList.toggle("pause", st.playing);
    if (!st.playing) {
      sync(true);
    }
    requestDraw();
  }

  function goTo(step, syncNow) {
    st.step = Math.min(Math.max(0, step), Math.max(0, st.nSteps - 1));
    st.pos = st.step;
    if (syncNow) {
      sync(true);
    }
  }

  function showSpeed() {
    for (const b of speedButtons) {
      b.classList.toggle("active", Number(b.dataset.speed) === model.speed);
    }
  }

  play.addEventListener("click", () => setPlaying(!st.playing));
  previous.addEventListener("click", () => {
    setPlaying(false);
    goTo(st.step > 0 ? st.step - 1 : st.nSteps - 1, true);
    requestDraw();
  });
  next.addEventListener("click", () => {
    setPlaying(false);
    goTo(st.step + 1 < st.nSteps ? st.step + 1 : 0, true);
    requestDraw();
  });
  slider.addEventListener("input", () => {
    // scrubbing is drawn here, at once; Python hears of it SCRUB_SYNC_MS after the last move (or on release)
    goTo(Number(slider.value), false);
    draw();
    if (st.scrubTimer != null) {
      clearTimeout(st.scrubTimer);
    }
    st.scrubTimer = setTimeout(() => {
      st.scrubTimer = null;
      sync(true);
    }, SCRUB_SYNC_MS);
  });
  slider.addEventListener("change", () => {  // the slider let go: Python hears at once
    if (st.scrubTimer != null) {
      clearTimeout(st.scrubTimer);
      st.scrubTimer = null;
    }
    sync(true);
  });
  for (const b of speedButtons) {
    b.addEventListener("click", () => {
      model.speed = Number(b.dataset.speed);
    });
  }
  layout.addEventListener("click", () => {
    st.overlay = !st.overlay;
    layout.textContent = st.overlay ? "side by side" : "overlay";
    requestDraw();
  });
  function resetView() {
    Object.assign(st, { azimuth: HOME.azimuth, elevation: HOME.elevation, zoom: HOME.zoom });
    requestDraw();
  }
  home.addEventListener("click", resetView);
  canvas.addEventListener("dblclick", resetView);

  let drag = null;
  canvas.addEventListener("pointerdown", (event) => {
    drag = { x: event.clientX, y: event.clientY, azimuth: st.azimuth, elevation: st.elevation };
    canvas.setPointerCapture(event.pointerId);
  });
  canvas.addEventListener("pointermove", (event) => {
    if (drag == null) {
      return;
    }
    st.azimuth = drag.azimuth - 0.5 * (event.clientX - drag.x);
    st.elevation = Math.min(85, Math.max(-10, drag.elevation + 0.4 * (event.clientY - drag.y)));
    requestDraw();
  });
  const endDrag = () => { drag = null; };
  canvas.addEventListener("pointerup", endDrag);
  canvas.addEventListener("pointercancel", endDrag);
  canvas.addEventListener("wheel", (event) => {
    event.preventDefault();
    st.zoom = Math.min(8, Math.max(0.25, st.zoom * Math.exp(-0.0015 * event.deltaY)));
    requestDraw();
  }, { passive: false });

  // ---------------------------------------------------------------------------------------------- from Python
  let reloadQueued = false;
  model.on(["positions", "alignment", "meta"], () => {
    if (!reloadQueued) {  // one reload for the three properties of one load()
      reloadQueued = true;
      queueMicrotask(() => {
        reloadQueued = false;
        load();
      });
    }
  });
  model.on("step", () => {
    if (model.step !== st.step) {  // set by Python (our own model.step = ... arrives here equal to st.step)
      st.sent = model.step;
      goTo(model.step, false);
      requestDraw();
    }
  });
  model.on("speed", () => {
    showSpeed();
    requestDraw();  // the caption's playing time follows the speed
  });
  model.on("view_size", () => {
    resize();
    requestDraw();
  });
  model.on("after_render", requestDraw);
  model.on("remove", () => {
    st.removed = true;
    if (st.frameRequest != null) {
      cancelAnimationFrame(st.frameRequest);
    }
    if (st.scrubTimer != null) {
      clearTimeout(st.scrubTimer);
    }
  });

  resize();
  showSpeed();
  load();
}
