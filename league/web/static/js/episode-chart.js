// The per-episode chart of an evaluation on a <canvas>: one bar per episode for its return,
// coloured by outcome, and the episode's mean speed as a line on the right-hand axis.

import { element } from "./dom.js";
import { number, outcomeText } from "./format.js";
import { OUTCOME_COLORS, SPEED_COLOR } from "./palette.js";

const MARGIN = { left: 52, right: 56, top: 14, bottom: 36 }; // CSS px
const AXIS_COLOR = "#58606a";

/** Draw `episodes` ([{index, return, mean_speed, outcome}]) and keep it drawn at the canvas' size. */
export function showEpisodeChart(canvas, legend, episodes) {
  canvas.setAttribute("role", "img");
  canvas.setAttribute("aria-label", chartSummary(episodes));
  legend.replaceChildren(...legendItems(episodes));
  const draw = () => drawEpisodeChart(canvas, episodes);
  if (canvas.resizeObserver) canvas.resizeObserver.disconnect();
  canvas.resizeObserver = new ResizeObserver(draw);
  canvas.resizeObserver.observe(canvas);
  draw();
}

export function drawEpisodeChart(canvas, episodes) {
  const ratio = window.devicePixelRatio || 1;
  const width = canvas.clientWidth;
  const height = canvas.clientHeight;
  if (!width || !height) return;
  canvas.width = Math.round(width * ratio);
  canvas.height = Math.round(height * ratio);
  const ctx = canvas.getContext("2d");
  ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
  ctx.fillStyle = "#ffffff";
  ctx.fillRect(0, 0, width, height);
  if (!episodes.length) return;

  const plot = { x: MARGIN.left, y: MARGIN.top, w: width - MARGIN.left - MARGIN.right, h: height - MARGIN.top - MARGIN.bottom };
  const returns = episodes.map((e) => e.return);
  const speeds = episodes.map((e) => e.mean_speed);
  const returnAxis = niceAxis(Math.min(0, ...returns), Math.max(0, ...returns));
  const speedAxis = niceAxis(0, Math.max(...speeds, 1e-6));
  const yReturn = (v) => plot.y + plot.h * (1 - (v - returnAxis.min) / (returnAxis.max - returnAxis.min));
  const ySpeed = (v) => plot.y + plot.h * (1 - (v - speedAxis.min) / (speedAxis.max - speedAxis.min));
  const band = plot.w / episodes.length;
  const xCentre = (i) => plot.x + band * (i + 0.5);

  ctx.font = "12px system-ui, sans-serif";
  drawGrid(ctx, plot, returnAxis, yReturn);
  // bars: return per episode, from the zero line
  const barWidth = Math.max(1, band * 0.75);
  episodes.forEach((episode, i) => {
    const top = yReturn(Math.max(episode.return, 0));
    const bottom = yReturn(Math.min(episode.return, 0));
    ctx.fillStyle = OUTCOME_COLORS[episode.outcome] || "#999999";
    ctx.fillRect(xCentre(i) - barWidth / 2, top, barWidth, Math.max(bottom - top, 1));
  });
  // line: mean speed per episode
  ctx.strokeStyle = SPEED_COLOR;
  ctx.lineWidth = 2;
  ctx.beginPath();
  speeds.forEach((speed, i) => (i ? ctx.lineTo(xCentre(i), ySpeed(speed)) : ctx.moveTo(xCentre(i), ySpeed(speed))));
  ctx.stroke();
  if (band >= 6) {
    speeds.forEach((speed, i) => {
      ctx.beginPath();
      ctx.arc(xCentre(i), ySpeed(speed), 3, 0, 2 * Math.PI);
      ctx.fillStyle = "#ffffff";
      ctx.fill();
      ctx.stroke();
    });
  }
  drawAxes(ctx, plot, episodes, returnAxis, yReturn, speedAxis, ySpeed, xCentre);
}

function drawGrid(ctx, plot, axis, y) {
  ctx.strokeStyle = "#e3e6ea";
  ctx.lineWidth = 1;
  for (const tick of axis.ticks) {
    ctx.beginPath();
    ctx.moveTo(plot.x, Math.round(y(tick)) + 0.5);
    ctx.lineTo(plot.x + plot.w, Math.round(y(tick)) + 0.5);
    ctx.stroke();
  }
  ctx.strokeStyle = AXIS_COLOR;
  ctx.beginPath();
  ctx.moveTo(plot.x, Math.round(y(0)) + 0.5);
  ctx.lineTo(plot.x + plot.w, Math.round(y(0)) + 0.5);
  ctx.stroke();
}

function drawAxes(ctx, plot, episodes, returnAxis, yReturn, speedAxis, ySpeed, xCentre) {
  ctx.fillStyle = AXIS_COLOR;
  ctx.textBaseline = "middle";
  ctx.textAlign = "right";
  for (const tick of returnAxis.ticks) ctx.fillText(formatTick(tick, returnAxis.step), plot.x - 6, yReturn(tick));
  ctx.fillStyle = SPEED_COLOR;
  ctx.textAlign = "left";
  for (const tick of speedAxis.ticks) ctx.fillText(formatTick(tick, speedAxis.step), plot.x + plot.w + 6, ySpeed(tick));
  // episode numbers: about 10 labels at most
  ctx.fillStyle = AXIS_COLOR;
  ctx.textAlign = "center";
  ctx.textBaseline = "top";
  const every = Math.max(1, Math.ceil(episodes.length / 10));
  episodes.forEach((episode, i) => {
    if (i % every === 0) ctx.fillText(String(i + 1), xCentre(i), plot.y + plot.h + 4);
  });
  ctx.fillText("episode", plot.x + plot.w / 2, plot.y + plot.h + 19);
  verticalLabel(ctx, "return", 12, plot.y + plot.h / 2, AXIS_COLOR);
  verticalLabel(ctx, "mean speed", plot.x + plot.w + MARGIN.right - 10, plot.y + plot.h / 2, SPEED_COLOR);
}

function verticalLabel(ctx, text, x, y, color) {
  ctx.save();
  ctx.translate(x, y);
  ctx.rotate(-Math.PI / 2);
  ctx.fillStyle = color;
  ctx.textAlign = "center";
  ctx.textBaseline = "middle";
  ctx.fillText(text, 0, 0);
  ctx.restore();
}

/** Round axis bounds and about five ticks at 1, 2 or 5 times a power of ten. */
export function niceAxis(min, max) {
  if (max - min < 1e-9) max = min + 1;
  const raw = (max - min) / 5;
  const power = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 5, 10].map((m) => m * power).find((s) => s >= raw);
  const lo = Math.floor(min / step) * step;
  const hi = Math.ceil(max / step) * step;
  const ticks = [];
  for (let v = lo; v <= hi + step / 2; v += step) ticks.push(Number(v.toFixed(10)));
  return { min: lo, max: hi, step, ticks };
}

function formatTick(value, step) {
  const decimals = Math.max(0, -Math.floor(Math.log10(step)));
  return value.toFixed(decimals);
}

function legendItems(episodes) {
  const outcomes = [...new Set(episodes.map((e) => e.outcome))];
  const items = outcomes.map((outcome) => {
    const swatch = element("span", { className: "swatch", attrs: { "aria-hidden": "true" } });
    swatch.style.background = OUTCOME_COLORS[outcome] || "#999999";
    const count = episodes.filter((e) => e.outcome === outcome).length;
    return element("li", {}, swatch, `${outcomeText(outcome)} (${count})`);
  });
  const line = element("span", { className: "swatch line", attrs: { "aria-hidden": "true" } });
  line.style.background = SPEED_COLOR;
  items.push(element("li", {}, line, "mean speed (right axis)"));
  return items;
}

function chartSummary(episodes) {
  if (!episodes.length) return "No episodes.";
  const finished = episodes.filter((e) => e.outcome === "finished").length;
  const returns = episodes.map((e) => e.return);
  const speeds = episodes.map((e) => e.mean_speed);
  return `Chart of ${episodes.length} episodes: ${finished} finished; return from ${number(Math.min(...returns))} ` +
    `to ${number(Math.max(...returns))}; mean speed from ${number(Math.min(...speeds), 3)} to ${number(Math.max(...speeds), 3)}. ` +
    "The table below lists every episode.";
}
