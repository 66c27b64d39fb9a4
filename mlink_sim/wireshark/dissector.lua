-- The dissector code. `T` (above, generated) holds every table; nothing below names a code or a bit of its own.
-- Wireshark 4.0 runs Lua 5.2 (bit32); later versions keep Wireshark's own `bit` module.

local bitops = bit32 or bit
local band, bxor, rshift = bitops.band, bitops.bxor, bitops.rshift

local mlink = Proto("mlink", "MECHATROLINK over UDP (mlink-sim)")

local F = {}
local fields = {}
local function field(key, f)
  F[key] = f
  fields[#fields + 1] = f
  return f
end

local function lower(s) return string.lower(s) end

-- value strings: Lua tables keyed by the code
local fcs_status_names = { [0] = "Bad", [1] = "Good" }

field("magic", ProtoField.uint8("mlink.magic", "Magic", base.HEX))
field("link", ProtoField.uint8("mlink.link", "Link", base.HEX, T.links))
field("kind", ProtoField.uint8("mlink.kind", "Kind", base.HEX, T.kinds))
field("station", ProtoField.uint8("mlink.station", "Station", base.HEX))
field("cycle", ProtoField.uint32("mlink.cycle", "Cycle", base.DEC))
field("tcycle_ns", ProtoField.uint32("mlink.tcycle_ns", "Transmission cycle (ns)", base.DEC))
field("data_size", ProtoField.uint8("mlink.data_size", "Data size", base.DEC))
field("code", ProtoField.uint8("mlink.cmd", "Command", base.HEX, T.commands))
field("cmd_name", ProtoField.string("mlink.cmd.name", "Command name"))
field("subcode", ProtoField.uint8("mlink.subcmd", "Sub-command", base.HEX, T.commands))
field("subcmd_name", ProtoField.string("mlink.subcmd.name", "Sub-command name"))
field("wdt", ProtoField.uint8("mlink.wdt", "WDT", base.HEX))
field("rwdt", ProtoField.uint8("mlink.rwdt", "RWDT", base.HEX))
field("alarm", ProtoField.uint8("mlink.alarm", "ALARM", base.HEX))
field("alarm_name", ProtoField.string("mlink.alarm.name", "Alarm name"))
field("status", ProtoField.uint16("mlink.status", "STATUS", base.HEX))
field("substatus", ProtoField.uint8("mlink.substatus", "SUBSTATUS", base.HEX))
field("cmd_ctrl", ProtoField.uint16("mlink.cmd_ctrl", "CMD_CTRL", base.HEX))
field("cmd_stat", ProtoField.uint16("mlink.cmd_stat", "CMD_STAT", base.HEX))
field("sub_ctrl", ProtoField.uint16("mlink.sub_ctrl", "SUB_CTRL", base.HEX))
field("sub_stat", ProtoField.uint16("mlink.sub_stat", "SUB_STAT", base.HEX))
field("raw", ProtoField.bytes("mlink.raw", "Body (no layout for this code)"))
field("main", ProtoField.none("mlink.main", "Main"))
field("sub", ProtoField.none("mlink.sub", "Sub"))
field("fcs", ProtoField.uint16("mlink.fcs", "FCS", base.HEX))
field("fcs_computed", ProtoField.uint16("mlink.fcs.computed", "FCS computed", base.HEX))
field("fcs_status", ProtoField.uint8("mlink.fcs.status", "FCS status", base.DEC, fcs_status_names))
field("param", ProtoField.string("mlink.param", "Parameter"))
field("param_value", ProtoField.string("mlink.param.value", "Value"))
-- the exchange, as a request/response protocol's dissector gives it (dns.response_in, dns.time): a response is
-- matched to its command by master, link, station and cycle (a response echoes its command's cycle)
field("response_in", ProtoField.framenum("mlink.response_in", "Response in", base.NONE, frametype.RESPONSE))
field("response_to", ProtoField.framenum("mlink.response_to", "Response to", base.NONE, frametype.REQUEST))
field("time", ProtoField.relative_time("mlink.time", "Response time"))
field("late", ProtoField.bool("mlink.late", "Late (after the station's next command)"))
field("gap", ProtoField.relative_time("mlink.gap", "Time since the station's previous command"))
field("speed_ref_hz", ProtoField.double("mlink.speed_ref.hz", "Speed reference (Hz)"))
field("output_freq_hz", ProtoField.double("mlink.output_freq.hz", "Output frequency (Hz)"))

-- bit fields: { {mask, name}, ... } under a parent of `width` bits
local function bit_fields(prefix, bits, width)
  local out = {}
  for _, b in ipairs(bits) do
    local abbr = prefix .. "." .. lower(b[2])
    out[#out + 1] = { field(abbr, ProtoField.bool(abbr, b[2], width, nil, b[1])) }
  end
  return out
end

-- packed fields (CMD_CTRL, CMD_STAT, SUB_STAT): {name, mask}; a single bit is a bool, a wider one a number
local packed_names = { cmd_alm = T.cmd_alm, comm_alm = T.comm_alm, subcmd_alm = T.subcmd_alm }
local function packed_fields(prefix, spec, width)
  local out = {}
  for _, p in ipairs(spec) do
    local name, mask = p[1], p[2]
    local abbr = prefix .. "." .. name
    local f
    if band(mask, mask - 1) == 0 then
      f = ProtoField.bool(abbr, string.upper(name), width, nil, mask)
    else
      f = ProtoField.uint16(abbr, string.upper(name), base.HEX, packed_names[name], mask)
    end
    out[#out + 1] = { field(abbr, f) }
  end
  return out
end

local STATUS_BITS = bit_fields("mlink.status", T.status_bits, 16)
local SUBSTATUS_BITS = bit_fields("mlink.substatus", T.substatus_bits, 8)
local CMD_CTRL_FIELDS = packed_fields("mlink.cmd_ctrl", T.cmd_ctrl, 16)
local CMD_STAT_FIELDS = packed_fields("mlink.cmd_stat", T.cmd_stat, 16)
local SUB_STAT_FIELDS = packed_fields("mlink.sub_stat", T.sub_stat, 16)

-- body fields: one display-filter field per name (mlink.no, mlink.speed_ref ...)
local BODY = {}
local BODY_BITS = {}
for name, spec in pairs(T.body_fields) do
  local wtype, b = spec[1], spec[2]
  local abbr = "mlink." .. name
  local f
  if wtype == "bytes" then
    f = ProtoField.bytes(abbr, name)
  else  -- uint8 ... int32, as wide as the widest layout using the name
    f = ProtoField[wtype](abbr, name, b == "hex" and base.HEX or base.DEC)
  end
  BODY[name] = field("body." .. name, f)
end
local WIDTH = { uint8 = 8, uint16 = 16, uint32 = 32 }
for name, bits in pairs(T.body_bits) do
  BODY_BITS[name] = bit_fields("mlink." .. name, bits, WIDTH[T.body_fields[name][1]])
end

mlink.fields = fields

local ef_bad_fcs = ProtoExpert.new("mlink.fcs.bad", "Bad FCS", expert.group.CHECKSUM, expert.severity.ERROR)
local ef_size = ProtoExpert.new("mlink.size.bad", "Datagram size not allowed on this link", expert.group.MALFORMED,
  expert.severity.ERROR)
local ef_header = ProtoExpert.new("mlink.header.bad", "Unknown link or kind", expert.group.MALFORMED,
  expert.severity.ERROR)
local ef_alarm = ProtoExpert.new("mlink.alarm.raised", "Alarm or warning reported", expert.group.RESPONSE_CODE,
  expert.severity.WARN)
local ef_unknown = ProtoExpert.new("mlink.unknown", "Command code without a layout", expert.group.UNDECODED,
  expert.severity.NOTE)
local ef_late = ProtoExpert.new("mlink.late.answer", "Answer after the station's next command", expert.group.SEQUENCE,
  expert.severity.WARN)
local ef_sequence = ProtoExpert.new("mlink.sequence.bad", "Cycle number out of sequence", expert.group.SEQUENCE,
  expert.severity.WARN)
mlink.experts = { ef_bad_fcs, ef_size, ef_header, ef_alarm, ef_unknown, ef_late, ef_sequence }

local function crc16_x25(tvb, n)
  local crc = 0xFFFF
  local bytes = tvb:bytes(0, n)
  for i = 0, n - 1 do
    crc = bxor(rshift(crc, 8), T.crc_table[band(bxor(crc, bytes:get_index(i)), 0xFF) + 1])
  end
  return bxor(crc, 0xFFFF)
end

local function contains(list, value)
  for _, v in ipairs(list) do
    if v == value then return true end
  end
  return false
end

local function add_bits(item, range, bits)
  for _, b in ipairs(bits) do item:add_le(b[1], range) end
end

-- name of an ALARM byte: the card's own codes (SI-T3 Tables 23/25), then the drive table the STATUS bits
-- point at (Table 26 with ALM, Table 27 with WARNG only), as mlink_sim.wire.describe does
local function alarm_name(code, status)
  local name = T.m2_alarm[code]
  if name then return name end
  if band(status, T.status_alm_bit) ~= 0 then
    name = T.drive_alarm[code]
  elseif band(status, T.status_warng_bit) ~= 0 then
    name = T.drive_warning[code]
  end
  return name or string.format("0x%02x", code)
end

-- parameters by name: the card of a station from the preference mlink.cards ("si-t3", "22H=si-t-v7,0x21=si-t3"),
-- the capture's card notes ("station 21H: card SI-T3 ..."), or the link (T.link_card); the card picks the table
local function card_key(text) return lower((string.gsub(text, "[^%w]", ""))) end
local pref_cards, pref_all = {}, nil
local noted = {}
local comment_field = nil
do
  local ok, f = pcall(Field.new, "frame.comment")
  if ok then comment_field = f end
end

local function parse_cards(text)
  pref_cards, pref_all = {}, nil
  for item in string.gmatch(text or "", "[^,%s]+") do
    local addr, card = string.match(item, "^(.-)=(.+)$")
    if addr then
      local hex = string.match(addr, "^0[xX](%x+)$") or string.match(addr, "^(%x+)[hH]$")
      if hex then pref_cards[tonumber(hex, 16)] = card_key(card) end
    else
      pref_all = card_key(item)
    end
  end
end

-- INV_CTL's speed in Hz: the station's units (o1-03 / n035) from its card note ("…, speed in 0.01 Hz counts"),
-- else the default both drives share: o1-03 = 0 (A1000, SI-T3 Table 4 / SI-ET3 Table 7) and n035 = 0
-- (VS-606V7), 0.01 Hz per count (docs/drive-model.md, "Units of the reference")
local DEFAULT_HZ_PER_COUNT = 0.01
local noted_hz = {}

local function learn_cards()
  if comment_field == nil then return end
  for _, fi in ipairs({ comment_field() }) do
    local text = tostring(fi.value)
    local station, card = string.match(text, "^station (%x%x)H: card (%S+)")
    if station then
      noted[tonumber(station, 16)] = card_key(card)
      local hz = string.match(text, "speed in ([%d%.eE+-]+) Hz counts")
      if hz then noted_hz[tonumber(station, 16)] = tonumber(hz) end
    end
  end
end

local function speed_hz(root, range, station, raw, f)
  local per = noted_hz[station]
  local source = per and "the capture's note" or "default: o1-03 = 0 / n035 = 0"
  per = per or DEFAULT_HZ_PER_COUNT
  local hz = math.abs(raw) * per
  local item = root:add(f, range, hz)
  item:set_text(string.format("%s: %.2f Hz (%g Hz per count, %s)", f == F.speed_ref_hz and "Speed reference"
    or "Output frequency", hz, per, source))
  item:set_generated()
end

-- the exchanges, kept from the first pass (frame numbers: what every later pass and the statistic read)
local exchanges = {}    -- frame -> { station, link, kind, command, t, tcycle, rt, to, late, gap, seq_bad }
local commands_at = {}  -- "master|link|station|cycle" -> frame of the command
local answer_of = {}    -- command frame -> response frame
local last_command = {} -- "master|link|station" -> { cycle, t, first }: its latest command, the first one's cycle

local function exchange(pinfo, link, kind, station, cycle, tcycle, command)
  local n = pinfo.number
  local x = exchanges[n]
  if x ~= nil or pinfo.visited then return x end
  local is_cmd = kind == 1
  local master = is_cmd and (tostring(pinfo.src) .. ":" .. pinfo.src_port)
    or (tostring(pinfo.dst) .. ":" .. pinfo.dst_port)
  local who = string.format("%s|%d|%d", master, link, station)
  local key = who .. "|" .. cycle
  x = { station = station, link = link, kind = kind, command = command, t = pinfo.rel_ts, tcycle = tcycle }
  if is_cmd then
    local last = last_command[who]
    if last ~= nil then
      x.gap = pinfo.rel_ts - last.t
      x.seq_bad = cycle <= last.cycle
    end
    last_command[who] = { cycle = cycle, t = pinfo.rel_ts, first = last and last.first or cycle }
    commands_at[key] = n
  else
    local cmd = commands_at[key]
    local last = last_command[who]
    if cmd ~= nil and answer_of[cmd] == nil then
      answer_of[cmd] = n
      x.to = cmd
      x.rt = pinfo.rel_ts - exchanges[cmd].t
      x.late = last.cycle ~= cycle
    elseif last ~= nil and cycle >= last.first then  -- a second answer, or one to a cycle never commanded
      x.seq_bad = true
    end
  end
  exchanges[n] = x
  return x
end

-- seconds (a difference of pinfo.rel_ts, the time since the first packet: a double, good to the nanosecond) as an
-- NSTime
local function nstime(seconds)
  local whole = math.floor(seconds)
  return NSTime.new(whole, math.floor((seconds - whole) * 1e9 + 0.5))
end

local function add_exchange(root, tvb, pinfo, x)
  if x == nil then return end
  local envelope = tvb(4, 4)
  if x.kind == 1 then
    local rsp = answer_of[pinfo.number]
    if rsp then root:add(F.response_in, envelope, rsp):set_generated() end
    if x.gap then root:add(F.gap, envelope, nstime(x.gap)):set_generated() end
    if x.seq_bad then root:add_proto_expert_info(ef_sequence, "Cycle number not above the station's previous "
      .. "command's") end
  elseif x.seq_bad then
    root:add_proto_expert_info(ef_sequence, "An answer to a cycle no command had, or a second answer")
  elseif x.to then
    root:add(F.response_to, envelope, x.to):set_generated()
    root:add(F.time, envelope, nstime(x.rt)):set_generated()
    local late = root:add(F.late, envelope, x.late)
    late:set_generated()
    if x.late then late:add_proto_expert_info(ef_late, "Answer after the station's next command") end
  end
end

local function param_table(link, station)
  local card = pref_cards[station] or pref_all or noted[station] or T.link_card[link]
  local family = card and T.card_family[card]
  return family and T.params[family]
end

-- the value of a 2-byte register as Param.format writes it ("1.0 s", "150%", "24H")
local function param_text(row, raw)
  if row[4] and raw >= 0x8000 then raw = raw - 0x10000 end
  if string.sub(row[2], -2) == "XH" then return string.format(row[2], raw) .. row[5] end
  return string.format(row[2], raw * row[3]) .. row[5]
end

-- returns, for a PRM_RD / PRM_WR body, what naming its parameter needs once the frame's refusal bits are known
local function dissect_body(tree, range, gen, slot, code, label, station)
  local layout = T.bodies[gen][slot][code]
  local names = T.gen_commands[gen]
  local sub = tree:add(F[string.lower(label)], range)
  sub:set_text(string.format("%s: %s (%02XH)", label, names[code] or "unknown", code))
  if layout == nil then
    sub:add(F.raw, range)
    sub:add_proto_expert_info(ef_unknown, string.format("%s code %02XH has no layout", label, code))
    return nil
  end
  local prm = contains(T.prm_commands, names[code]) and { tree = sub } or nil
  for _, f in ipairs(layout) do
    local name, off, size = f[1], f[2], f[3]
    local item = sub:add_le(BODY[name], range(off, size))
    if BODY_BITS[name] then add_bits(item, range(off, size), BODY_BITS[name]) end
    if names[code] == "INV_CTL" and (name == "speed_ref" or name == "output_freq") then
      speed_hz(sub, range(off, size), station, range(off, size):le_uint(), F[name .. "_hz"])
    end
    if prm then
      if name == "no" then prm.no, prm.no_range = range(off, size):le_uint(), range(off, size)
      elseif name == "size" then prm.size = range(off, size):le_uint()
      elseif name == "data" or name == "parameter" then prm.data = range(off, size) end
    end
  end
  if prm then prm.head = string.format("%s: %s (%02XH)", label, names[code], code) end
  return prm
end

-- the parameter of a PRM_RD / PRM_WR body by name, with its value unless the station refused the command
local function name_param(prm, params, refused)
  if prm == nil or params == nil or prm.no == nil then return nil end
  local row = params[prm.no]
  if row == nil then return nil end
  local text = string.format("%s (%04XH)", row[1], prm.no)
  prm.tree:add(F.param, prm.no_range, row[1]):set_generated()
  if prm.data ~= nil and prm.size == 2 and not refused then
    local value = param_text(row, prm.data(0, 2):le_uint())
    prm.tree:add(F.param_value, prm.data(0, 2), value):set_generated()
    text = text .. " = " .. value
  end
  prm.tree:set_text(prm.head .. " " .. text)
  return text
end

local function dissect(tvb, pinfo, tree)
  local len = tvb:len()
  pinfo.cols.protocol = "MLINK"
  local root = tree:add(mlink, tvb(), "MECHATROLINK (mlink-sim)")
  local shortest = T.header_size + 17 + T.fcs_size
  local longest = T.header_size + 64 + T.fcs_size
  if len < shortest or len > longest then
    root:add_proto_expert_info(ef_size, string.format("%d bytes: a datagram is %d to %d bytes", len, shortest, longest))
    return len
  end
  for _, f in ipairs(T.envelope) do
    root:add_le(F[f[1]], tvb(f[2], f[3]))
  end
  local n = len - T.header_size - T.fcs_size
  local size_item = root:add(F.data_size, tvb(T.header_size, n), n)
  size_item:set_generated()
  local fcs_range = tvb(len - T.fcs_size, T.fcs_size)
  local fcs_rx = fcs_range:le_uint()
  local fcs_calc = crc16_x25(tvb, len - T.fcs_size)
  local fcs_item = root:add_le(F.fcs, fcs_range)
  root:add(F.fcs_computed, fcs_range, fcs_calc):set_generated()
  local good = fcs_rx == fcs_calc
  root:add(F.fcs_status, fcs_range, good and 1 or 0):set_generated()
  local station = tvb(3, 1):uint()
  local link, kind = tvb(1, 1):uint(), tvb(2, 1):uint()
  local info = string.format("%02XH", station)
  if not good then
    fcs_item:add_proto_expert_info(ef_bad_fcs, string.format("Bad FCS: 0x%04x, computed 0x%04x", fcs_rx, fcs_calc))
    info = info .. " [BAD FCS]"
  end
  local gen = T.link_gen[link]
  if gen == nil or T.kinds[kind] == nil then
    root:add_proto_expert_info(ef_header, string.format("link %02XH, kind %02XH", link, kind))
    pinfo.cols.info = info .. " unknown link or kind"
    return len
  end
  if not contains(T.data_sizes[link], n) then
    size_item:add_proto_expert_info(ef_size, string.format("%d data bytes on %s", n, T.links[link]))
    pinfo.cols.info = info .. string.format(" %d data bytes on %s", n, T.links[link])
    return len
  end
  local is_cmd = kind == 1
  local frame = T.frames[gen][is_cmd and "cmd" or "rsp"][n]
  local data = tvb(T.header_size, n)
  local names = T.gen_commands[gen]
  local code, subcode, status, alarm, substatus, main_prm, sub_prm
  local cmd_alm_v, subcmd_alm_v = 0, 0
  local notes = {}
  learn_cards()
  for _, f in ipairs(frame) do
    local name, off, size = f[1], f[2], f[3]
    local range = data(off, size)
    if name == "code" then
      code = range:uint()
      root:add(F.code, range)
      root:add(F.cmd_name, range, names[code] or string.format("0x%02x", code)):set_generated()
    elseif name == "subcode" then
      subcode = range:uint()
      root:add(F.subcode, range)
      root:add(F.subcmd_name, range, names[subcode] or string.format("0x%02x", subcode)):set_generated()
    elseif name == "main" then
      main_prm = dissect_body(root, range, gen, is_cmd and "cmd_main" or "rsp_main", code, "Main", station)
    elseif name == "sub" then
      sub_prm = dissect_body(root, range, gen, is_cmd and "cmd_sub" or "rsp_sub", subcode, "Sub", station)
    elseif name == "status" then
      status = range:le_uint()
      add_bits(root:add_le(F.status, range), range, STATUS_BITS)
    elseif name == "substatus" then
      substatus = range:uint()
      add_bits(root:add_le(F.substatus, range), range, SUBSTATUS_BITS)
    elseif name == "alarm" then
      alarm = range:uint()
      root:add(F.alarm, range)
    elseif name == "cmd_ctrl" then
      add_bits(root:add_le(F.cmd_ctrl, range), range, CMD_CTRL_FIELDS)
    elseif name == "cmd_stat" then
      local v = range:le_uint()
      add_bits(root:add_le(F.cmd_stat, range), range, CMD_STAT_FIELDS)
      local cmd_alm, comm_alm = band(rshift(v, 8), 0xF), band(rshift(v, 12), 0xF)
      cmd_alm_v = cmd_alm
      if cmd_alm ~= 0 then notes[#notes + 1] = "CMD_ALM " .. (T.cmd_alm[cmd_alm] or cmd_alm) end
      if comm_alm ~= 0 then notes[#notes + 1] = "COMM_ALM " .. (T.comm_alm[comm_alm] or comm_alm) end
    elseif name == "sub_ctrl" then
      root:add_le(F.sub_ctrl, range)
    elseif name == "sub_stat" then
      local v = range:le_uint()
      add_bits(root:add_le(F.sub_stat, range), range, SUB_STAT_FIELDS)
      local subcmd_alm = band(rshift(v, 8), 0xF)
      subcmd_alm_v = subcmd_alm
      if subcmd_alm ~= 0 then notes[#notes + 1] = "SUBCMD_ALM " .. (T.subcmd_alm[subcmd_alm] or subcmd_alm) end
    elseif F[name] then
      root:add(F[name], range)
    end
  end
  local params = param_table(link, station)
  local main_param = name_param(main_prm, params, contains(T.refusals_ml2, alarm or 0) or cmd_alm_v ~= 0)
  local sub_param = name_param(sub_prm, params, band(substatus or 0, T.substatus_errors) ~= 0 or subcmd_alm_v ~= 0)
  if alarm ~= nil and alarm ~= 0 then
    local aname = alarm_name(alarm, status or 0)
    root:add(F.alarm_name, data(1, 1), aname):set_generated()
    notes[#notes + 1] = string.format("ALARM %02XH %s", alarm, aname)
  end
  if #notes > 0 then
    root:add_proto_expert_info(ef_alarm, table.concat(notes, ", "))
  end
  root:append_text(string.format(", %s %s, station %02XH, %s", T.links[link], T.kinds[kind], station,
    names[code] or string.format("0x%02x", code)))
  info = string.format("%s %s %s", info, is_cmd and "cmd" or "rsp", names[code] or string.format("0x%02x", code))
  if main_param then info = info .. " " .. main_param end
  if subcode ~= nil then info = info .. " / " .. (names[subcode] or string.format("0x%02x", subcode)) end
  if sub_param then info = info .. " " .. sub_param end
  local cycle = tvb(4, 4):le_uint()
  info = info .. string.format(" cycle %d", cycle)
  if #notes > 0 then info = info .. " [" .. table.concat(notes, ", ") .. "]" end
  pinfo.cols.info = info
  if good then
    add_exchange(root, tvb, pinfo, exchange(pinfo, link, kind, station, cycle, tvb(8, 4):le_uint(),
      names[code] or string.format("%02XH", code)))
  elseif not pinfo.visited then
    exchanges[pinfo.number] = { station = station, link = link, kind = kind, fcs_bad = true }
  end
  return len
end

function mlink.dissector(tvb, pinfo, tree)
  return dissect(tvb, pinfo, tree)
end

-- heuristic: the magic byte, a known link and kind, and a data size that link allows
local function heuristic(tvb, pinfo, tree)
  local len = tvb:len()
  if len < T.header_size + 17 + T.fcs_size or len > T.header_size + 64 + T.fcs_size then return false end
  if tvb(0, 1):uint() ~= T.magic then return false end
  local link, kind = tvb(1, 1):uint(), tvb(2, 1):uint()
  if T.link_gen[link] == nil or T.kinds[kind] == nil then return false end
  if not contains(T.data_sizes[link], len - T.header_size - T.fcs_size) then return false end
  dissect(tvb, pinfo, tree)
  return true
end

mlink.prefs.ports = Pref.range("UDP ports", "47001",
  "UDP ports decoded as MECHATROLINK (the heuristic finds the others)", 65535)

local registered = nil
local function register_ports()
  local udp = DissectorTable.get("udp.port")
  if registered ~= nil then udp:remove(registered, mlink) end
  registered = mlink.prefs.ports
  udp:add(registered, mlink)
end

mlink.prefs.cards = Pref.string("Cards of stations", "",
  "The card of MECHATROLINK-II stations, for parameter names and units: si-t3 or si-t-v7 for all, or "
  .. "22H=si-t-v7,0x21=si-t3 (ML-III is the SI-ET3, ML-I the SI-T/V7; a capture's card notes are read too)")

function mlink.prefs_changed()
  register_ports()
  parse_cards(mlink.prefs.cards)
end

register_ports()
mlink:register_heuristic("udp", heuristic)

function mlink.init()
  exchanges, commands_at, answer_of, last_command, noted_hz = {}, {}, {}, {}, {}
end

-- The MECHATROLINK response-time statistic (tshark -z mlink,srt[,FILTER]; Wireshark: Statistics > MECHATROLINK
-- Response Times): per station and command the commands, responses, lost and late answers and the response time
-- (min, avg, p50, p99, max); per station the gaps between its commands and the FCS and sequence errors, as
-- mlink-sim decode --pcap FILE --stats counts them (docs/capture.md)
local function percentile(sorted, p)
  local rank = math.max(1, math.ceil(p / 100 * #sorted))
  return sorted[rank]
end

local function ms(seconds) return string.format("%9.3f", seconds * 1e3) end

-- min, avg, p50, p99, max of a list of seconds, in ms (dashes for none); sorts the list
local function figures(values)
  if #values == 0 then return string.rep(string.format("%9s ", "-"), 5) end
  table.sort(values)
  local sum = 0
  for _, v in ipairs(values) do sum = sum + v end
  return table.concat({ ms(values[1]), ms(sum / #values), ms(percentile(values, 50)), ms(percentile(values, 99)),
    ms(values[#values]) }, " ")
end

local function srt_tap(filter)
  local tap = Listener.new(nil, filter and filter ~= "" and ("mlink && (" .. filter .. ")") or "mlink")
  local per, stations, pending
  local function reset()
    per, stations, pending = {}, {}, {}
  end
  reset()
  tap.reset = reset
  local function station_of(x)
    local st = stations[x.station]
    if st == nil then
      st = { gaps = {}, fcs = 0, seq = 0, last_t = 0 }
      stations[x.station] = st
    end
    return st
  end
  local function row(x, command)
    local key = string.format("%02XH %s", x.station, command)
    local r = per[key]
    if r == nil then
      r = { cmd = 0, rsp = 0, late = 0, lost = 0, times = {} }
      per[key] = r
    end
    return r
  end
  function tap.packet(pinfo)
    local x = exchanges[pinfo.number]
    if x == nil then return end
    local st = station_of(x)
    if x.fcs_bad then
      st.fcs = st.fcs + 1
      return
    end
    st.last_t = math.max(st.last_t, x.t)
    if x.kind == 1 then
      row(x, x.command).cmd = row(x, x.command).cmd + 1
      if x.gap then st.gaps[#st.gaps + 1] = x.gap end
      if x.seq_bad then st.seq = st.seq + 1 end
      pending[pinfo.number] = x
    else
      local command = x.to and exchanges[x.to].command or x.command
      local r = row(x, command)
      r.rsp = r.rsp + 1
      if x.seq_bad then st.seq = st.seq + 1 end
      if x.to then
        r.times[#r.times + 1] = x.rt
        if x.late then r.late = r.late + 1 end
        pending[x.to] = nil
      end
    end
  end
  local function text()
    for _, x in pairs(pending) do  -- unanswered, unless within a cycle of the end of its station's capture
      if stations[x.station].last_t - x.t >= x.tcycle / 1e9 then
        local r = row(x, x.command)
        r.lost = r.lost + 1
      end
    end
    local lines = { string.rep("=", 100), "MECHATROLINK response times (mlink-sim), ms",
      string.format("%-8s %-16s %9s %9s %5s %5s %9s %9s %9s %9s %9s", "station", "command", "commands",
        "responses", "lost", "late", "min", "avg", "p50", "p99", "max") }
    local keys = {}
    for key in pairs(per) do keys[#keys + 1] = key end
    table.sort(keys)
    for _, key in ipairs(keys) do
      local r = per[key]
      local station, command = string.match(key, "^(%S+) (.+)$")
      lines[#lines + 1] = string.format("%-8s %-16s %9d %9d %5d %5d %s", station, command, r.cmd, r.rsp, r.lost,
        r.late, figures(r.times))
    end
    lines[#lines + 1] = ""
    lines[#lines + 1] = string.format("%-8s %9s %9s %9s %9s %9s  %10s %15s", "station", "gap min", "avg", "p50", "p99",
      "max", "FCS errors", "sequence errors")
    local addrs = {}
    for a in pairs(stations) do addrs[#addrs + 1] = a end
    table.sort(addrs)
    for _, a in ipairs(addrs) do
      local st = stations[a]
      lines[#lines + 1] = string.format("%02XH      %s  %10d %15d", a, figures(st.gaps), st.fcs, st.seq)
    end
    lines[#lines + 1] = string.rep("=", 100)
    return table.concat(lines, "\n")
  end
  return tap, text
end

register_stat_cmd_arg("mlink,srt", function(arg)
  local filter = string.match(arg or "", "^mlink,srt,(.+)$")
  local tap, text = srt_tap(filter)
  function tap.draw() print(text()) end
end)

if gui_enabled() then
  register_menu("MECHATROLINK Response Times", function()
    local win = TextWindow.new("MECHATROLINK response times (mlink-sim)")
    local tap, text = srt_tap(nil)
    function tap.draw() win:set(text()) end
    win:set_atclose(function() tap:remove() end)
    retap_packets()
  end, MENU_STAT_GENERIC)
end
