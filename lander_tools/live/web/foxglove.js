// A small client of the Foxglove WebSocket protocol (subprotocol "foxglove.sdk.v1", the one
// foxglove-sdk's server speaks; messages as in the ws-protocol spec v1). No dependency: the page
// must work with nothing fetched from the internet. Used by app.js; see docs/live.md.
"use strict";

class FoxgloveClient {
  constructor(url) {
    this.url = url;
    this.channels = new Map();      // topic -> advertised channel {id, topic, encoding, schemaName}
    this.services = new Map();      // name -> service {id, name, type}
    this.subs = new Map();          // subscription id -> callback(payloadBytes, timestampNs)
    this.wanted = new Map();        // topic -> callback, subscribed when advertised
    this.clientChannels = new Map();// topic -> client channel id
    this.pendingCalls = new Map();  // call id -> {resolve, reject}
    this.pendingParams = new Map(); // request id -> resolve
    this.nextId = 1;
    this.onStatus = () => {};
    this.onParameters = () => {};
    this.onTime = () => {};
    this.onOpen = () => {};
    this.onClose = () => {};
    this.decoder = new TextDecoder();
    this.encoder = new TextEncoder();
    this.connect();
  }

  connect() {
    const ws = new WebSocket(this.url, ["foxglove.sdk.v1"]);
    ws.binaryType = "arraybuffer";
    ws.onopen = () => this.onOpen();
    ws.onclose = () => { this.onClose(); setTimeout(() => this.reconnect(), 1000); };
    ws.onmessage = (ev) => (typeof ev.data === "string" ? this.onText(JSON.parse(ev.data)) : this.onBinary(ev.data));
    this.ws = ws;
  }

  reconnect() {
    this.channels.clear(); this.services.clear(); this.subs.clear(); this.clientChannels.clear();
    this.connect();
  }

  onText(msg) {
    switch (msg.op) {
      case "advertise":
        for (const ch of msg.channels) {
          this.channels.set(ch.topic, ch);
          if (this.wanted.has(ch.topic)) this.doSubscribe(ch.topic);
        }
        break;
      case "advertiseServices":
        for (const s of msg.services) this.services.set(s.name, s);
        break;
      case "parameterValues": {
        const done = msg.id && this.pendingParams.get(msg.id);
        if (done) { this.pendingParams.delete(msg.id); done(msg.parameters); }
        this.onParameters(msg.parameters);
        break;
      }
      case "status": this.onStatus(msg); break;
      case "serviceCallFailure": {
        const p = this.pendingCalls.get(msg.callId);
        if (p) { this.pendingCalls.delete(msg.callId); p.reject(new Error(msg.message)); }
        break;
      }
      default: break;
    }
  }

  onBinary(buf) {
    const view = new DataView(buf);
    const op = view.getUint8(0);
    if (op === 1) {  // message data: subscription id, log time (ns), payload
      const cb = this.subs.get(view.getUint32(1, true));
      if (cb) cb(new Uint8Array(buf, 13), view.getBigUint64(5, true));
    } else if (op === 2) {  // time
      this.onTime(view.getBigUint64(1, true));
    } else if (op === 3) {  // service call response: service id, call id, encoding, payload
      const callId = view.getUint32(5, true);
      const encLen = view.getUint32(9, true);
      const payload = new Uint8Array(buf, 13 + encLen);
      const p = this.pendingCalls.get(callId);
      if (p) { this.pendingCalls.delete(callId); p.resolve(JSON.parse(this.decoder.decode(payload))); }
    }
  }

  // Subscribe to a JSON channel; cb(object, timestampNs). Re-subscribes after a reconnect.
  subscribeJson(topic, cb) {
    this.wanted.set(topic, (bytes, t) => cb(JSON.parse(this.decoder.decode(bytes)), t));
    if (this.channels.has(topic)) this.doSubscribe(topic);
  }

  doSubscribe(topic) {
    const id = this.nextId++;
    this.subs.set(id, this.wanted.get(topic));
    this.send({ op: "subscribe", subscriptions: [{ id, channelId: this.channels.get(topic).id }] });
  }

  send(obj) { if (this.ws.readyState === WebSocket.OPEN) this.ws.send(JSON.stringify(obj)); }

  // Client publish: advertise the topic once (JSON encoding), then send a message data frame.
  publishJson(topic, obj) {
    if (this.ws.readyState !== WebSocket.OPEN) return false;
    if (!this.clientChannels.has(topic)) {
      const id = this.nextId++;
      this.clientChannels.set(topic, id);
      this.send({ op: "advertise", channels: [{ id, topic, encoding: "json", schemaName: topic }] });
    }
    const payload = this.encoder.encode(JSON.stringify(obj));
    const buf = new Uint8Array(5 + payload.length);
    const view = new DataView(buf.buffer);
    view.setUint8(0, 1);
    view.setUint32(1, this.clientChannels.get(topic), true);
    buf.set(payload, 5);
    this.ws.send(buf);
    return true;
  }

  // Call a service with a JSON request; resolves with the JSON response.
  callService(name, request) {
    const svc = this.services.get(name);
    if (!svc) return Promise.reject(new Error(`service ${name} not advertised (is the bridge connected?)`));
    const callId = this.nextId++;
    const enc = this.encoder.encode("json");
    const payload = this.encoder.encode(JSON.stringify(request || {}));
    const buf = new Uint8Array(13 + enc.length + payload.length);
    const view = new DataView(buf.buffer);
    view.setUint8(0, 2);
    view.setUint32(1, svc.id, true);
    view.setUint32(5, callId, true);
    view.setUint32(9, enc.length, true);
    buf.set(enc, 13);
    buf.set(payload, 13 + enc.length);
    return new Promise((resolve, reject) => {
      this.pendingCalls.set(callId, { resolve, reject });
      this.ws.send(buf);
    });
  }

  // Set parameters; resolves with the values in force afterwards (the server's answer).
  setParameters(parameters) {
    const id = `set-${this.nextId++}`;
    return new Promise((resolve) => {
      this.pendingParams.set(id, resolve);
      this.send({ op: "setParameters", parameters, id });
    });
  }

  getParameters(names) {
    const id = `get-${this.nextId++}`;
    return new Promise((resolve) => {
      this.pendingParams.set(id, resolve);
      this.send({ op: "getParameters", parameterNames: names, id });
    });
  }
}
