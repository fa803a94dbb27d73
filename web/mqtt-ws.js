// A small MQTT 3.1.1 client over WebSocket for the cell page (docs/web-dashboard.md, "The cell
// page"). It only reads: CONNECT with a user name and password, SUBSCRIBE, PUBLISH received
// (QoS 0 and 1, retained or not; QoS 1 is acknowledged with PUBACK), PINGREQ keep-alive and
// reconnection with back-off. It never publishes: a page that cannot send a command cannot be
// made to, whatever the broker's ACL says (the broker's web user may not write either).
//
// Why our own: Debian packages no browser MQTT client (node-mqtt is for node), and a page in
// the shop must work offline from the files ncd ships. The protocol part needed is small:
//
// - Transport: a WebSocket with the subprotocol "mqtt" and binary frames (MQTT 3.1.1, 6.0). A
//   frame may hold part of a packet or several packets: bytes are appended to a buffer and
//   whole packets taken from its front.
// - Packets: a fixed header (type << 4 | flags), the remaining length as a variable-length
//   integer (7 bits a byte, the high bit "more", at most 4 bytes), then the body. Strings are a
//   16-bit big-endian length and UTF-8 bytes.
// - Session: CONNECT (protocol "MQTT", level 4, clean session, user name and password flags,
//   the keep-alive in seconds), then CONNACK: 0 accepted, else refused with its code named (4:
//   bad user name or password, 5: not authorised, which is what mosquitto answers a wrong
//   password with). On acceptance every subscription is sent
//   again (clean session: the broker forgot them), and the broker sends the retained messages
//   of each filter, so a reconnected page gets every machine's online and state back at once.
// - Keep-alive: a PINGREQ once half the keep-alive has passed without one; no PINGRESP within
//   the other half, or no CONNACK within connectTimeoutS, and the socket is closed.
// - Reconnection: any close or error schedules the next attempt after a delay that starts at
//   minDelayS and doubles per failed attempt up to maxDelayS; an accepted CONNACK resets it.
//
// Usage:
//   const c = new MqttWsClient({url, username, password, subscriptions: [[filter, qos], …],
//                               onMessage(topic, text, retained) {}, onState(state, detail) {}});
//   c.start(); … c.stop();
// onState's state: "connecting", "connected", "waiting" (detail: why, and the delay), "stopped".
"use strict";

class MqttWsClient {
  constructor(options) {
    this.url = options.url;
    this.username = options.username || "";
    this.password = options.password || "";
    this.clientId = options.clientId || "ncd-cell-" + Math.random().toString(36).slice(2, 12);
    this.keepAliveS = options.keepAliveS || 20;
    this.connectTimeoutS = options.connectTimeoutS || 10;
    this.minDelayS = options.minDelayS || 0.5;
    this.maxDelayS = options.maxDelayS || 10;
    this.subscriptions = options.subscriptions || [];
    this.onMessage = options.onMessage || (() => {});
    this.onState = options.onState || (() => {});
    this.delayS = this.minDelayS;
    this.ws = null;
    this.timers = [];
    this.stopped = true;
    this.stats = { connects: 0, messages: 0, bytes: 0, refusals: 0 };
    this.encoder = new TextEncoder();
    this.decoder = new TextDecoder("utf-8");
  }

  start() {
    this.stopped = false;
    this.open();
  }

  stop() {
    this.stopped = true;
    this.clearTimers();
    if (this.ws) {
      try {
        if (this.ws.readyState === WebSocket.OPEN) this.ws.send(new Uint8Array([0xe0, 0x00]));
        this.ws.close();
      } catch (e) {
        // closing anyway
      }
      this.ws = null;
    }
    this.onState("stopped", "");
  }

  // One connection attempt.
  open() {
    this.clearTimers();
    this.buffer = new Uint8Array(0);
    this.accepted = false;
    this.onState("connecting", this.url);
    let ws;
    try {
      ws = new WebSocket(this.url, ["mqtt"]);
    } catch (e) {
      this.retry("cannot open " + this.url + ": " + e.message);
      return;
    }
    ws.binaryType = "arraybuffer";
    this.ws = ws;
    ws.onopen = () => {
      ws.send(this.connectPacket());
      this.lastSentMs = Date.now();
    };
    ws.onmessage = (ev) => this.receive(ws, new Uint8Array(ev.data));
    ws.onerror = () => {}; // onclose follows with the code
    ws.onclose = (ev) => {
      if (this.ws !== ws) return;
      this.ws = null;
      this.retry(this.closeReason || "the connection closed (code " + ev.code + ")");
    };
    this.closeReason = "";
    this.timers.push(
      setTimeout(() => this.drop(ws, "no CONNACK within " + this.connectTimeoutS + " s"),
                 this.connectTimeoutS * 1000));
  }

  // Closes this socket on purpose, saying why; onclose schedules the retry.
  drop(ws, reason) {
    if (this.ws !== ws) return;
    this.closeReason = reason;
    ws.close();
  }

  retry(reason) {
    this.clearTimers();
    if (this.stopped) return;
    const delay = this.delayS;
    this.delayS = Math.min(this.delayS * 2, this.maxDelayS);
    this.onState("waiting", reason + "; next attempt in " + delay.toFixed(1) + " s");
    this.timers.push(setTimeout(() => this.open(), delay * 1000));
  }

  clearTimers() {
    for (const t of this.timers) {
      clearTimeout(t);
      clearInterval(t);
    }
    this.timers = [];
  }

  // Appends a frame's bytes and handles every whole packet at the front of the buffer.
  receive(ws, bytes) {
    const joined = new Uint8Array(this.buffer.length + bytes.length);
    joined.set(this.buffer, 0);
    joined.set(bytes, this.buffer.length);
    this.buffer = joined;
    for (;;) {
      const head = MqttWsClient.remainingLength(this.buffer);
      if (head === null) return; // the length is not whole yet
      if (head.error) return this.drop(ws, head.error);
      const end = head.offset + head.length;
      if (this.buffer.length < end) return;
      const packet = this.buffer.subarray(0, end);
      this.buffer = this.buffer.slice(end);
      this.handle(ws, packet[0], packet.subarray(head.offset));
    }
  }

  // The remaining length at bytes[1..]: {length, offset of the body}, null if incomplete.
  static remainingLength(bytes) {
    let length = 0;
    for (let i = 1; i <= 4; ++i) {
      if (i >= bytes.length) return null;
      length += (bytes[i] & 0x7f) * Math.pow(128, i - 1);
      if ((bytes[i] & 0x80) === 0) return { length, offset: i + 1 };
    }
    return { error: "a remaining length longer than 4 bytes" };
  }

  handle(ws, header, body) {
    const type = header >> 4;
    if (type === 2) return this.connack(ws, body); // CONNACK
    if (type === 3) return this.publish(ws, header, body); // PUBLISH
    if (type === 9) return this.suback(ws, body); // SUBACK
    if (type === 13) this.pongMs = Date.now(); // PINGRESP
  }

  connack(ws, body) {
    const code = body.length >= 2 ? body[1] : -1;
    if (code !== 0) {
      ++this.stats.refusals;
      const names = {
        1: "the broker does not take MQTT 3.1.1",
        2: "the client id was refused",
        3: "the broker is unavailable",
        4: "bad user name or password",
        5: "not authorised: a wrong user name or password, or a user the broker refuses",
      };
      return this.drop(ws, "the broker refused the connection (code " + code + ": " +
                               (names[code] || "unknown") + ")");
    }
    this.clearTimers();
    this.accepted = true;
    this.delayS = this.minDelayS;
    ++this.stats.connects;
    if (this.subscriptions.length > 0) ws.send(this.subscribePacket(1));
    this.pongMs = Date.now();
    this.pingMs = undefined;
    const halfMs = (this.keepAliveS * 1000) / 2;
    this.timers.push(setInterval(() => this.keepAlive(ws, halfMs), Math.min(halfMs, 1000)));
    this.onState("connected", this.url);
  }

  keepAlive(ws, halfMs) {
    const now = Date.now();
    if (this.pingMs !== undefined && this.pongMs < this.pingMs && now - this.pingMs > halfMs) {
      return this.drop(ws, "no PINGRESP within " + (halfMs / 1000).toFixed(1) + " s");
    }
    if (now - this.lastSentMs >= halfMs && (this.pingMs === undefined || this.pongMs >= this.pingMs)) {
      ws.send(new Uint8Array([0xc0, 0x00])); // PINGREQ
      this.lastSentMs = now;
      this.pingMs = now;
    }
  }

  suback(ws, body) {
    for (let i = 2; i < body.length; ++i) {
      if (body[i] === 0x80) {
        const filter = this.subscriptions[i - 2] ? this.subscriptions[i - 2][0] : "?";
        this.onState("connected", "the broker refused the subscription to " + filter);
      }
    }
  }

  publish(ws, header, body) {
    const qos = (header >> 1) & 3;
    const retained = (header & 1) === 1;
    const topicLength = (body[0] << 8) | body[1];
    const topic = this.decoder.decode(body.subarray(2, 2 + topicLength));
    let at = 2 + topicLength;
    if (qos > 0) {
      const id0 = body[at], id1 = body[at + 1];
      at += 2;
      if (qos === 1) ws.send(new Uint8Array([0x40, 0x02, id0, id1])); // PUBACK
    }
    ++this.stats.messages;
    this.stats.bytes += body.length;
    this.onMessage(topic, this.decoder.decode(body.subarray(at)), retained);
  }

  // A packet: the header byte, the remaining length, the body.
  static packet(header, parts) {
    let length = 0;
    for (const p of parts) length += p.length;
    const len = [];
    let n = length;
    do {
      let b = n % 128;
      n = Math.floor(n / 128);
      if (n > 0) b |= 0x80;
      len.push(b);
    } while (n > 0);
    const out = new Uint8Array(1 + len.length + length);
    out[0] = header;
    out.set(len, 1);
    let at = 1 + len.length;
    for (const p of parts) {
      out.set(p, at);
      at += p.length;
    }
    return out;
  }

  string(s) {
    const b = this.encoder.encode(s);
    const out = new Uint8Array(2 + b.length);
    out[0] = b.length >> 8;
    out[1] = b.length & 0xff;
    out.set(b, 2);
    return out;
  }

  connectPacket() {
    let flags = 0x02; // clean session
    const payload = [this.string(this.clientId)];
    if (this.username) {
      flags |= 0x80;
      payload.push(this.string(this.username));
      if (this.password) {
        flags |= 0x40;
        payload.push(this.string(this.password));
      }
    }
    const head = new Uint8Array([0, 4, 0x4d, 0x51, 0x54, 0x54, 4, flags,
                                 this.keepAliveS >> 8, this.keepAliveS & 0xff]);
    return MqttWsClient.packet(0x10, [head, ...payload]);
  }

  subscribePacket(id) {
    const parts = [new Uint8Array([id >> 8, id & 0xff])];
    for (const [filter, qos] of this.subscriptions) {
      parts.push(this.string(filter));
      parts.push(new Uint8Array([qos]));
    }
    return MqttWsClient.packet(0x82, parts);
  }
}
