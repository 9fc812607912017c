// The cars' colours are the toolkit's (league.render.CAR_COLORS, matplotlib's "tab10": ten
// distinct colours), which the server writes into every page, so that a car looks here as in
// `league race --save race.gif`. Cars also differ by marker shape: the two cars of a shape (car i
// and car i + 5) keep colours apart for people with a red-green colour-vision deficiency too.
// Outcomes and the speed line use the Okabe–Ito palette, as the pages' CSS does.

const CAR_COLORS = document.body.dataset.carColors.split(" ");
const CAR_SHAPES = ["circle", "square", "triangle", "diamond", "pentagon"];

/** Car `index`'s colour and shape; past the tenth car the shapes shift, so 50 cars have 50 pairs. */
export function carStyle(index) {
  const lap = Math.floor(index / CAR_COLORS.length);
  return { color: CAR_COLORS[index % CAR_COLORS.length], shape: CAR_SHAPES[(index + lap) % CAR_SHAPES.length] };
}

export const OUTCOME_COLORS = {
  finished: "#009E73",
  off_road: "#D55E00",
  wrong_direction: "#CC79A7",
  too_slow: "#E69F00",
  timeout: "#56B4E9",
  dnf: "#000000",
};
export const SPEED_COLOR = "#0072B2";

/** Trace a marker shape of radius r centred on (x, y) into ctx's current path. */
export function traceShape(ctx, shape, x, y, r) {
  ctx.beginPath();
  if (shape === "circle") {
    ctx.arc(x, y, r, 0, 2 * Math.PI);
  } else if (shape === "square") {
    ctx.rect(x - r * 0.85, y - r * 0.85, r * 1.7, r * 1.7);
  } else {
    const corners = { triangle: 3, diamond: 4, pentagon: 5 }[shape];
    for (let k = 0; k < corners; k++) {
      const angle = -Math.PI / 2 + (2 * Math.PI * k) / corners;
      const radius = shape === "triangle" ? r * 1.2 : r * 1.1;
      ctx.lineTo(x + radius * Math.cos(angle), y + radius * Math.sin(angle));
    }
  }
  ctx.closePath();
}

/** A small SVG of a car's marker, for legends (the same shape and colour as on the canvas). */
export function markerIcon(index) {
  const { color, shape } = carStyle(index);
  const svg = document.createElementNS("http://www.w3.org/2000/svg", "svg");
  svg.setAttribute("viewBox", "-10 -10 20 20");
  svg.setAttribute("aria-hidden", "true");
  svg.setAttribute("class", "marker-icon");
  const path = document.createElementNS("http://www.w3.org/2000/svg", "path");
  path.setAttribute("d", shapePath(shape, 7));
  path.setAttribute("fill", color);
  path.setAttribute("stroke", "#000");
  path.setAttribute("stroke-width", "1.5");
  svg.append(path);
  return svg;
}

function shapePath(shape, r) {
  if (shape === "circle") return `M ${-r} 0 A ${r} ${r} 0 1 0 ${r} 0 A ${r} ${r} 0 1 0 ${-r} 0 Z`;
  if (shape === "square") return `M ${-r * 0.85} ${-r * 0.85} h ${r * 1.7} v ${r * 1.7} h ${-r * 1.7} Z`;
  const corners = { triangle: 3, diamond: 4, pentagon: 5 }[shape];
  const radius = shape === "triangle" ? r * 1.2 : r * 1.1;
  const points = [];
  for (let k = 0; k < corners; k++) {
    const angle = -Math.PI / 2 + (2 * Math.PI * k) / corners;
    points.push(`${(radius * Math.cos(angle)).toFixed(2)} ${(radius * Math.sin(angle)).toFixed(2)}`);
  }
  return `M ${points.join(" L ")} Z`;
}
