// Draws a race on a <canvas>: the track (road, borders, obstacles, start line) once into an
// off-screen background, then per frame each car's coloured trail and its marker.

import { carStyle, traceShape } from "./palette.js";

export const OFF_ROAD = "#eef3e6"; // pale green, as in the toolkit's pictures
export const ROAD = "#b9b9b9";
// A marker's edge: black (10:1 on the road, 18:1 off it) inside a white halo (for dark obstacles).
export const MARKER_EDGE = "#000000";
const MARKER_HALO = "#ffffff";
const BORDER = "#5d646b";
const OBSTACLE = "#1e1e1e";
const MARGIN = 0.04; // world units around the track
const MAX_HEIGHT_FRACTION = 0.78; // of the window's height
export const MARKER_RADIUS = 9; // CSS px: room for a two-digit number
const HEADING_TICK = 17; // CSS px, from the marker's centre

export class RacePainter {
  constructor(canvas, geometry, replay) {
    this.canvas = canvas;
    this.geometry = geometry;
    this.replay = replay;
    const xs = geometry.outer.map((p) => p[0]);
    const ys = geometry.outer.map((p) => p[1]);
    this.world = { minX: Math.min(...xs) - MARGIN, maxX: Math.max(...xs) + MARGIN,
                   minY: Math.min(...ys) - MARGIN, maxY: Math.max(...ys) + MARGIN };
    this.step = 0;
    this.width = 0;
    this.observer = new ResizeObserver(() => this.fit());
    this.observer.observe(canvas.parentElement);
    this.fit();
  }

  /** Size the canvas to its container (and the window's height), at the screen's pixel density. */
  fit() {
    const available = this.canvas.parentElement.clientWidth;
    const { minX, maxX, minY, maxY } = this.world;
    const aspect = (maxY - minY) / (maxX - minX);
    let width = available;
    let height = width * aspect;
    const maxHeight = window.innerHeight * MAX_HEIGHT_FRACTION;
    if (height > maxHeight) {
      height = maxHeight;
      width = height / aspect;
    }
    width = Math.floor(width);
    if (!width || (width === this.width && this.background)) return;
    this.width = width;
    this.height = Math.floor(height);
    this.ratio = window.devicePixelRatio || 1;
    this.scale = width / (maxX - minX); // CSS px per world unit
    this.canvas.style.width = `${width}px`;
    this.canvas.style.height = `${this.height}px`;
    this.canvas.width = Math.round(width * this.ratio);
    this.canvas.height = Math.round(this.height * this.ratio);
    this.background = this.paintBackground();
    this.draw(this.step);
  }

  toPixels(x, y) {
    return [(x - this.world.minX) * this.scale, (this.world.maxY - y) * this.scale];
  }

  paintBackground() {
    const layer = document.createElement("canvas");
    layer.width = this.canvas.width;
    layer.height = this.canvas.height;
    const ctx = layer.getContext("2d");
    ctx.setTransform(this.ratio, 0, 0, this.ratio, 0, 0);
    ctx.fillStyle = OFF_ROAD;
    ctx.fillRect(0, 0, this.width, this.height);
    // the road: between the outer and the inner border
    ctx.beginPath();
    this.tracePolyline(ctx, this.geometry.outer, true);
    this.tracePolyline(ctx, this.geometry.inner, true);
    ctx.fillStyle = ROAD;
    ctx.fill("evenodd");
    ctx.strokeStyle = BORDER;
    ctx.lineWidth = 1.2;
    ctx.stroke();
    this.paintObstacles(ctx);
    this.paintStart(ctx);
    return layer;
  }

  paintObstacles(ctx) {
    ctx.strokeStyle = OBSTACLE;
    ctx.lineCap = "square";
    ctx.lineWidth = Math.max(2, 2 * this.geometry.obstacle_half_width * this.scale);
    for (const [[x0, y0], [x1, y1]] of this.geometry.obstacles) {
      ctx.beginPath();
      ctx.moveTo(...this.toPixels(x0, y0));
      ctx.lineTo(...this.toPixels(x1, y1));
      ctx.stroke();
    }
    ctx.lineCap = "butt";
  }

  /** A chequered line across the road at the start, and an arrow for the direction of the race. */
  paintStart(ctx) {
    const { x, y, heading } = this.geometry.start;
    const half = (this.geometry.width / 2) * 1.1;
    const across = [-Math.sin(heading), Math.cos(heading)];
    const a = this.toPixels(x - across[0] * half, y - across[1] * half);
    const b = this.toPixels(x + across[0] * half, y + across[1] * half);
    const thickness = Math.max(3, this.geometry.width * this.scale * 0.18);
    ctx.lineWidth = thickness;
    ctx.strokeStyle = "#ffffff";
    ctx.beginPath();
    ctx.moveTo(...a);
    ctx.lineTo(...b);
    ctx.stroke();
    ctx.setLineDash([thickness, thickness]);
    ctx.strokeStyle = "#000000";
    ctx.stroke();
    ctx.setLineDash([]);
    // arrow
    const length = Math.max(14, this.geometry.width * this.scale * 1.2);
    const [px, py] = this.toPixels(x, y);
    const dx = Math.cos(heading);
    const dy = -Math.sin(heading); // canvas y grows downwards
    const tip = [px + dx * length * 1.6, py + dy * length * 1.6];
    ctx.strokeStyle = "#000000";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.moveTo(px + dx * length * 0.5, py + dy * length * 0.5);
    ctx.lineTo(...tip);
    ctx.moveTo(tip[0] - dx * 6 - dy * 5, tip[1] - dy * 6 + dx * 5);
    ctx.lineTo(...tip);
    ctx.lineTo(tip[0] - dx * 6 + dy * 5, tip[1] - dy * 6 - dx * 5);
    ctx.stroke();
  }

  tracePolyline(ctx, points, closed) {
    points.forEach(([x, y], k) => (k ? ctx.lineTo(...this.toPixels(x, y)) : ctx.moveTo(...this.toPixels(x, y))));
    if (closed) ctx.closePath();
  }

  /** Draw the race at `step`: trails up to there, then every car's marker on top. */
  draw(step) {
    this.step = step;
    if (!this.background) return;
    const ctx = this.canvas.getContext("2d");
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.drawImage(this.background, 0, 0);
    ctx.setTransform(this.ratio, 0, 0, this.ratio, 0, 0);
    ctx.lineJoin = "round";
    ctx.lineCap = "round";
    for (let i = 0; i < this.replay.carCount; i++) this.drawTrail(ctx, i, step);
    for (let i = 0; i < this.replay.carCount; i++) {
      const { x, y, heading } = this.replay.position(i, step);
      paintMarker(ctx, i, ...this.toPixels(x, y), heading);
    }
  }

  drawTrail(ctx, i, step) {
    const car = this.replay.cars[i];
    const last = Math.min(step, this.replay.lastStep[i]);
    if (last < 1) return;
    ctx.beginPath();
    for (let k = 0; k <= last; k++) {
      const [px, py] = this.toPixels(car.x[k], car.y[k]);
      if (k) ctx.lineTo(px, py);
      else ctx.moveTo(px, py);
    }
    ctx.strokeStyle = "rgba(0, 0, 0, 0.55)"; // a dark edge keeps light colours visible on the road
    ctx.lineWidth = 4.5;
    ctx.stroke();
    ctx.strokeStyle = carStyle(i).color;
    ctx.lineWidth = 2.5;
    ctx.stroke();
  }

  destroy() {
    this.observer.disconnect();
  }
}

/** Car `index`'s marker centred on (px, py) CSS px: a tick for its heading, its shape in its colour, its number. */
export function paintMarker(ctx, index, px, py, heading) {
  const { color, shape, label, labelColor } = carStyle(index);
  ctx.strokeStyle = MARKER_EDGE;
  ctx.lineWidth = 2;
  ctx.beginPath();
  ctx.moveTo(px, py);
  ctx.lineTo(px + HEADING_TICK * Math.cos(heading), py - HEADING_TICK * Math.sin(heading));
  ctx.stroke();
  traceShape(ctx, shape, px, py, MARKER_RADIUS);
  ctx.strokeStyle = MARKER_HALO;
  ctx.lineWidth = 4;
  ctx.stroke();
  ctx.fillStyle = color;
  ctx.fill();
  ctx.strokeStyle = MARKER_EDGE;
  ctx.lineWidth = 2;
  ctx.stroke();
  ctx.fillStyle = labelColor;
  ctx.font = `700 ${label.length > 1 ? 9 : 11}px system-ui, sans-serif`;
  ctx.textAlign = "center";
  ctx.textBaseline = "middle";
  ctx.fillText(label, px, py + 0.5);
}
