// The trajectory plot of the page: the camera path seen from above, the two world axes along
// which the reference path extends most, at equal scale, with tick values in metres, start
// and end markers, and round line joins (a wide line with mitred joins draws spikes at
// sharp turns).
//
// drawTrajectory(canvas, estimate, groundTruth): each a list of [stamp, x, y, z] (metres).

// A tick step of 1, 2 or 5 times a power of ten giving about `want` ticks over `span`.
function tickStep(span, want) {
  const raw = span / Math.max(want, 1);
  const power = 10 ** Math.floor(Math.log10(raw));
  return [1, 2, 5, 10].map((m) => m * power).find((s) => s >= raw) ?? raw;
}

function format(v, step) {
  const digits = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
  return v.toFixed(digits);
}

export function drawTrajectory(canvas, est, gt) {
  const g = canvas.getContext("2d");
  g.fillStyle = "#fff";
  g.fillRect(0, 0, canvas.width, canvas.height);
  const ref = gt.length ? gt : est;
  if (!ref.length) return;
  const extent = [1, 2, 3].map((k) => {
    const v = ref.map((p) => p[k]);
    return Math.max(...v) - Math.min(...v);
  });
  const axes = [1, 2, 3].sort((a, b) => extent[b - 1] - extent[a - 1]).slice(0, 2).sort();
  const all = [...est, ...gt];
  const lo = axes.map((k) => Math.min(...all.map((p) => p[k])));
  const hi = axes.map((k) => Math.max(...all.map((p) => p[k])));
  // Room for the tick labels on the left and at the bottom.
  const box = { left: 62, right: canvas.width - 16, top: 34, bottom: canvas.height - 44 };
  const scale = Math.min(
    (box.right - box.left) / Math.max(hi[0] - lo[0], 1e-6),
    (box.bottom - box.top) / Math.max(hi[1] - lo[1], 1e-6),
  );
  // Centred in the box; the box's corners in world units.
  const mid = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2];
  const centre = [(box.left + box.right) / 2, (box.top + box.bottom) / 2];
  const at = (p) => [
    centre[0] + (p[axes[0]] - mid[0]) * scale,
    centre[1] - (p[axes[1]] - mid[1]) * scale,
  ];
  const world = [
    [mid[0] - (centre[0] - box.left) / scale, mid[0] + (box.right - centre[0]) / scale],
    [mid[1] - (box.bottom - centre[1]) / scale, mid[1] + (centre[1] - box.top) / scale],
  ];

  // Ticks and their values.
  g.font = "12px sans-serif";
  g.strokeStyle = "#e4e4e4";
  g.fillStyle = "#444";
  g.lineWidth = 1;
  for (const [axis, [a, b]] of world.entries()) {
    const step = tickStep(b - a, 5);
    for (let v = Math.ceil(a / step) * step; v <= b + 1e-9; v += step) {
      g.beginPath();
      if (axis === 0) {
        const x = centre[0] + (v - mid[0]) * scale;
        g.moveTo(x, box.top);
        g.lineTo(x, box.bottom);
        g.stroke();
        g.textAlign = "center";
        g.fillText(format(v, step), x, box.bottom + 16);
      } else {
        const y = centre[1] - (v - mid[1]) * scale;
        g.moveTo(box.left, y);
        g.lineTo(box.right, y);
        g.stroke();
        g.textAlign = "right";
        g.fillText(format(v, step), box.left - 6, y + 4);
      }
    }
  }
  g.strokeStyle = "#999";
  g.strokeRect(box.left, box.top, box.right - box.left, box.bottom - box.top);

  const path = (points, color, width) => {
    if (!points.length) return;
    g.strokeStyle = color;
    g.lineWidth = width;
    g.lineJoin = "round";
    g.lineCap = "round";
    g.beginPath();
    points.forEach((p, i) => (i ? g.lineTo(...at(p)) : g.moveTo(...at(p))));
    g.stroke();
  };
  // The ground truth wide and pale under the estimate: at sub-millimetre errors the two
  // lines coincide.
  path(gt, "#a9c3ee", 7);
  path(est, "#dc3c1e", 1.5);
  // Start: a green disc; end: a dark square (of the estimate, else the ground truth).
  const track = est.length ? est : gt;
  const [sx, sy] = at(track[0]);
  g.fillStyle = "#1a9a3a";
  g.beginPath();
  g.arc(sx, sy, 6, 0, 2 * Math.PI);
  g.fill();
  const [ex, ey] = at(track[track.length - 1]);
  g.fillStyle = "#222";
  g.fillRect(ex - 5, ey - 5, 10, 10);

  const names = ["x", "y", "z"];
  g.textAlign = "left";
  g.fillStyle = "#222";
  g.font = "13px sans-serif";
  g.fillText(`${names[axes[0] - 1]} →, ${names[axes[1] - 1]} ↑ (world, metres)`, box.left, canvas.height - 6);
  const legend = [
    ["#5a86d6", "ground truth"],
    ["#dc3c1e", "estimate"],
    ["#1a9a3a", "● start"],
    ["#222", "■ end"],
  ];
  let x = box.left;
  for (const [color, text] of legend) {
    if (text === "ground truth" && !gt.length) continue;
    g.fillStyle = color;
    g.fillText(text, x, 20);
    x += g.measureText(text).width + 14;
  }
}
