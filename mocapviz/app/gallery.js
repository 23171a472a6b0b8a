// The dashboard's gallery of hits, run in the browser (a Panel JSComponent: see gallery.py), after skeleton.js.
//
// One page of a result table arrives at once (model.positions: float32 (sum n_i, J, 3) cm, y up, the cells' low-rate
// copies of their hits, concatenated; model.meta: lengths, rates (Hz), rows (the table's row of each cell), labels,
// bounds, parents, sides, columns, cell size) and is drawn on one Canvas 2D as a grid of cells: each cell a skeleton
// seen by a fixed camera, its hit's middle key pose, the hit's rank, name and seconds under it. The cell under the
// pointer plays its frames in a loop at their own rate. A click makes the cell's row the table's selection
// (model.selection, the table's row numbers: the page's player then plays it); a ctrl-, cmd- or shift-click adds the
// row to the selection or removes it (what the download under the table exports).
//
// For tests the canvas carries data-cells (cells on the page), data-drawn (cells drawn so far), data-hover (the
// cell under the pointer, -1 for none), data-hover-frame (the frame it shows), data-selected (the selected rows on
// the page, comma separated), data-loads (pages received so far) and data-cut (the cells whose title did not fit its
// lines and ends in "…"; the full title shows on hover as the canvas's tooltip).
//
// Review (model.reviewing, a user who may annotate): every cell has a ✓ and a ✗ button in its top right corner
// (REVIEW_BOX px each, ✗ in the corner); a click on one sets model.verdict = {row, verdict: "accept"|"reject", n}
// (n counts the clicks, so the same verdict twice is two changes) and selects nothing. model.states gives each cell's
// review ("accepted": ✓ filled green, "rejected": ✗ filled red); data-states lists them, comma separated.

const PAD = 6;  // px around a cell's skeleton
const ZOOM = 1.2;  // the cell's camera box a little larger than the cell: the box holds the floor and a margin
const BACKGROUND = { plain: "#ffffff", hover: "#f1f1f1", selected: "#dde9f8" };
const LINE = 13;  // px of a label line (11 px text)
const BREAKS = "_ -.";
const REVIEW_BOX = 18;  // px of a cell's ✓ and ✗ buttons (gallery.py REVIEW_BOX)
const REVIEW_COLOURS = { accepted: "#2e8b57", rejected: "#c0392b" };  // a title breaks after one of these where it can (a name's parts stay whole), else anywhere

function ellipsis(ctx, text, width) {
  if (ctx.measureText(text).width <= width) {
    return text;
  }
  let cut = text.length;
  while (cut > 0 && ctx.measureText(`${text.slice(0, cut)}…`).width > width) {
    cut -= 1;
  }
  return `${text.slice(0, cut)}…`;
}

// `text` in lines of at most `width` px, at most `most` of them (the last cut with "…" when it is longer still)
function wrapped(ctx, text, width, most) {
  const lines = [];
  let rest = text;
  while (lines.length < most - 1 && ctx.measureText(rest).width > width) {
    let cut = rest.length;
    while (cut > 1 && ctx.measureText(rest.slice(0, cut)).width > width) {
      cut -= 1;
    }
    const soft = Math.max(...[...BREAKS].map((c) => rest.lastIndexOf(c, cut - 1)));
    if (soft >= cut / 2) {
      cut = soft + 1;
    }
    lines.push(rest.slice(0, cut));
    rest = rest.slice(cut);
  }
  lines.push(ellipsis(ctx, rest, width));
  return lines;
}

export function render({ model, el }) {
  const root = element("div", "mvg");
  const canvas = element("canvas", "mv-gallery-canvas");
  root.append(canvas);
  el.append(root);
  const ctx = canvas.getContext("2d");
  const dpr = Math.max(1, window.devicePixelRatio || 1);
  const st = {
    cells: [], lengths: [], rates: [], rows: [], labels: [], bounds: [], parents: [], sides: [], nJoints: 0,
    columns: 1, cellW: 150, cellH: 150, labelH: 30, selected: new Set(), hover: -1, hoverStart: 0, hoverFrame: -1,
    drawn: 0, loads: 0, frameRequest: null, removed: false, cut: new Set(),
  };

  function load() {
    const meta = model.meta || {};
    const nJoints = meta.n_joints || 0;
    const data = new Float32Array(arrayBuffer(model.positions));
    st.lengths = meta.lengths || [];
    st.cells = [];
    let offset = 0;
    for (const n of st.lengths) {
      st.cells.push(data.subarray(offset, offset + n * nJoints * 3));
      offset += n * nJoints * 3;
    }
    Object.assign(st, {
      nJoints, rates: meta.rates || [], rows: meta.rows || [], labels: meta.labels || [], bounds: meta.bounds || [],
      parents: meta.parents || [], sides: meta.sides || [], sideColours: meta.side_colours || { c: "#3c3c3c" },
      columns: meta.columns || 1,
      cellW: (meta.cell || [150, 150])[0], cellH: (meta.cell || [150, 150])[1], labelH: meta.label_height || 30,
      hover: -1, hoverFrame: -1,
    });
    st.loads += 1;
    canvas.dataset.loads = String(st.loads);
    canvas.dataset.cells = String(st.cells.length);
    resize();
    drawAll();
  }

  function resize() {
    const lines = Math.max(1, Math.ceil(st.cells.length / st.columns));
    const width = st.columns * st.cellW;
    const height = lines * st.cellH;
    canvas.style.width = `${width}px`;
    canvas.style.height = `${height}px`;
    canvas.width = Math.round(width * dpr);
    canvas.height = Math.round(height * dpr);
  }

  function middle(i) {
    return Math.floor(st.lengths[i] / 2);
  }

  // ---------------------------------------------------------------------------------------------- drawing
  function drawCell(i, frame) {
    const { cellW: w, cellH: h, labelH } = st;
    const x = (i % st.columns) * w;
    const y = Math.floor(i / st.columns) * h;
    const selected = st.selected.has(st.rows[i]);
    ctx.save();
    ctx.beginPath();
    ctx.rect(x, y, w, h);
    ctx.clip();
    ctx.fillStyle = selected ? BACKGROUND.selected : i === st.hover ? BACKGROUND.hover : BACKGROUND.plain;
    ctx.fillRect(x, y, w, h);
    const cam = makeCamera(st.bounds[i], HOME.azimuth, HOME.elevation, ZOOM, w - 2 * PAD, h - labelH - PAD, x + PAD,
                           y + PAD);
    const screen = projectPose(cam, st.cells[i], frame * st.nJoints * 3, st.nJoints);
    const segs = [];
    poseBones(cam, screen, st.parents, st.sides, st.sideColours, 1, segs);
    drawPoses(ctx, segs, [[screen, 1]], 1.5);
    ctx.fillStyle = "#222";
    ctx.textBaseline = "top";
    const [title, seconds] = st.labels[i] || ["", ""];
    ctx.font = "bold 11px sans-serif";
    const lines = wrapped(ctx, title, w - 8, Math.max(1, Math.floor(labelH / LINE) - 1));
    lines.forEach((line, k) => ctx.fillText(line, x + 4, y + h - labelH + 2 + k * LINE));
    if (lines.join("") !== title) {
      st.cut.add(i);
    }
    ctx.font = "11px sans-serif";
    ctx.fillText(seconds, x + 4, y + h - LINE - 2);
    if (model.reviewing) {
      drawButtons(x, y, (model.states || [])[i] || "");
    }
    ctx.strokeStyle = selected ? "#1f5fa8" : "#dddddd";
    ctx.lineWidth = selected ? 3 : 1;
    ctx.strokeRect(x + 0.5, y + 0.5, w - 1, h - 1);
    ctx.restore();
    st.drawn += 1;
    canvas.dataset.drawn = String(st.drawn);
  }

  // the ✓ (accept) and ✗ (reject) boxes of the cell at (x, y): [verdict, left, top] each
  function buttonBoxes(x, y) {
    const top = y + 4;
    return [["accept", x + st.cellW - 2 * REVIEW_BOX - 8, top], ["reject", x + st.cellW - REVIEW_BOX - 4, top]];
  }

  function drawButtons(x, y, state) {
    ctx.font = "bold 13px sans-serif";
    ctx.textBaseline = "middle";
    ctx.textAlign = "center";
    for (const [verdict, left, top] of buttonBoxes(x, y)) {
      const on = (verdict === "accept" && state === "accepted") || (verdict === "reject" && state === "rejected");
      ctx.fillStyle = on ? REVIEW_COLOURS[state] : "#ffffff";
      ctx.fillRect(left, top, REVIEW_BOX, REVIEW_BOX);
      ctx.strokeStyle = "#999999";
      ctx.lineWidth = 1;
      ctx.strokeRect(left + 0.5, top + 0.5, REVIEW_BOX - 1, REVIEW_BOX - 1);
      ctx.fillStyle = on ? "#ffffff" : verdict === "accept" ? REVIEW_COLOURS.accepted : REVIEW_COLOURS.rejected;
      ctx.fillText(verdict === "accept" ? "✓" : "✗", left + REVIEW_BOX / 2, top + REVIEW_BOX / 2 + 1);
    }
    ctx.textAlign = "left";
    ctx.textBaseline = "top";
  }

  // the verdict of the button under a click on cell i, or null
  function buttonAt(i, event) {
    if (!model.reviewing) {
      return null;
    }
    const box = canvas.getBoundingClientRect();
    const px = event.clientX - box.left;
    const py = event.clientY - box.top;
    const x = (i % st.columns) * st.cellW;
    const y = Math.floor(i / st.columns) * st.cellH;
    const hit = buttonBoxes(x, y).find(([, l, t]) => px >= l && px < l + REVIEW_BOX && py >= t && py < t + REVIEW_BOX);
    return hit ? hit[0] : null;
  }

  let verdicts = 0;

  function drawAll() {
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.fillStyle = BACKGROUND.plain;
    ctx.fillRect(0, 0, canvas.width / dpr, canvas.height / dpr);
    st.cut = new Set();
    st.cells.forEach((_, i) => drawCell(i, i === st.hover && st.hoverFrame >= 0 ? st.hoverFrame : middle(i)));
    canvas.dataset.selected = st.rows.filter((row) => st.selected.has(row)).join(",");
    canvas.dataset.hover = String(st.hover);
    canvas.dataset.cut = [...st.cut].join(",");
    canvas.dataset.states = (model.states || []).join(",");
  }

  // ---------------------------------------------------------------------------------------------- hover: play
  function tick(time) {
    st.frameRequest = null;
    if (st.removed || !root.isConnected || st.hover < 0) {
      return;
    }
    const i = st.hover;
    const frame = Math.floor((Math.max(0, time - st.hoverStart) / 1000) * st.rates[i]) % st.lengths[i];
    if (frame !== st.hoverFrame) {
      st.hoverFrame = frame;
      ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
      drawCell(i, frame);
      canvas.dataset.hoverFrame = String(frame);
    }
    st.frameRequest = requestAnimationFrame(tick);
  }

  function hover(i) {
    if (i === st.hover) {
      return;
    }
    const before = st.hover;
    st.hover = i;
    st.hoverFrame = -1;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    if (before >= 0 && before < st.cells.length) {
      drawCell(before, middle(before));
    }
    canvas.dataset.hover = String(i);
    canvas.title = i >= 0 ? (st.labels[i] || []).join(" · ") : "";
    if (i >= 0) {
      st.hoverStart = performance.now();
      if (st.frameRequest == null) {
        st.frameRequest = requestAnimationFrame(tick);
      }
    }
  }

  function cellAt(event) {
    const box = canvas.getBoundingClientRect();
    const column = Math.floor((event.clientX - box.left) / st.cellW);
    const line = Math.floor((event.clientY - box.top) / st.cellH);
    const i = line * st.columns + column;
    return column >= 0 && column < st.columns && line >= 0 && i < st.cells.length ? i : -1;
  }

  canvas.addEventListener("pointermove", (event) => hover(cellAt(event)));
  canvas.addEventListener("pointerleave", () => hover(-1));
  canvas.addEventListener("click", (event) => {
    const i = cellAt(event);
    if (i < 0) {
      return;
    }
    const row = st.rows[i];
    const verdict = buttonAt(i, event);
    if (verdict) {
      verdicts += 1;
      model.verdict = { row, verdict, n: verdicts };
      return;
    }
    let selection = [row];
    if (event.ctrlKey || event.metaKey || event.shiftKey) {
      selection = (model.selection || []).filter((r) => r !== row);
      if (selection.length === (model.selection || []).length) {
        selection.push(row);
      }
    }
    st.selected = new Set(selection);
    drawAll();
    model.selection = selection;
  });

  // ---------------------------------------------------------------------------------------------- from Python
  let reloadQueued = false;
  model.on(["positions", "meta"], () => {
    if (!reloadQueued) {  // one reload for the two properties of one page
      reloadQueued = true;
      queueMicrotask(() => {
        reloadQueued = false;
        load();
      });
    }
  });
  model.on(["states", "reviewing"], () => drawAll());
  model.on("selection", () => {
    st.selected = new Set(model.selection || []);
    drawAll();
  });
  model.on("after_render", () => {
    resize();
    drawAll();
  });
  model.on("remove", () => {
    st.removed = true;
    if (st.frameRequest != null) {
      cancelAnimationFrame(st.frameRequest);
    }
  });

  st.selected = new Set(model.selection || []);
  load();
}
