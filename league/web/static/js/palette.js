// The cars' colours are the toolkit's (league.render.CAR_COLORS, matplotlib's "tab10": ten
// distinct colours), which the server writes into every page, so that a car looks here as in
// `league race --save race.gif`. Cars also differ by marker shape: the two cars of a shape (car i
// and car i + 5) keep colours apart for people with a red-green colour-vision deficiency too.
// Each marker also carries its car's number (the legend's), in black or white, whichever stands out
// more on its colour: the colours alone are not enough (several are as light as the road).
// Outcomes and the speed line use the Okabe–Ito palette, as the pages' CSS does.

const CAR_COLORS = document.body.dataset.carColors.split(" ");
const CAR_SHAPES = ["circle", "square", "triangle", "diamond", "pentagon"];

/**
 * Car `index`'s colour, shape, number (`label`) and the colour of that number; past the tenth car
 * the shapes shift, so 50 cars have 50 pairs.
 */
export function carStyle(index) {
  const lap = Math.floor(index / CAR_COLORS.length);
  const color = CAR_COLORS[index % CAR_COLORS.length];
  return { color, shape: CAR_SHAPES[(index + lap) % CAR_SHAPES.length], label: String(index + 1), labelColor: textColorOn(color) };
}

/** Black or white, whichever contrasts more with `color` (WCAG 2 relative luminance). */
function textColorOn(color) {
  const [r, g, b] = [1, 3, 5].map((k) => parseInt(color.slice(k, k + 2), 16) / 255)
    .map((c) => (c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4));
  const luminance = 0.2126 * r + 0.7152 * g + 0.0722 * b;
  return (luminance + 0.05) / 0.05 >= 1.05 / (luminance + 0.05) ? "#000000" : "#ffffff";
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

/** A small SVG of a car's marker, for legends (the same shape, colour and number as on the canvas). */
export function markerIcon(index) {
  const { color, shape, label, labelColor } = carStyle(index);
  const svg = document.createElementNS("http://www.w3.org/2000/svg", "svg");
  svg.setAttribute("viewBox", "-11 -11 22 22");
  svg.setAttribute("aria-hidden", "true");
  svg.setAttribute("class", "marker-icon");
  const path = document.createElementNS("http://www.w3.org/2000/svg", "path");
  path.setAttribute("d", shapePath(shape, 9));
  path.setAttribute("fill", color);
  path.setAttribute("stroke", "#000");
  path.setAttribute("stroke-width", "1.5");
  const number = document.createElementNS("http://www.w3.org/2000/svg", "text");
  Object.entries({ x: 0, y: 0.5, fill: labelColor, "font-size": label.length > 1 ? 7.5 : 9, "font-weight": 700,
    "text-anchor": "middle", "dominant-baseline": "central", "font-family": "system-ui, sans-serif" })
    .forEach(([name, value]) => number.setAttribute(name, value));
  number.textContent = label;
  svg.append(path, number);
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
