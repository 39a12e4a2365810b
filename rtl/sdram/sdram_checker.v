// sdram_checker: a datasheet timing checker for one SDR SDRAM device, observing its pins.
//
// Ref: Micron 256Mb SDR SDRAM (MT48LC16M16A2) datasheet, Table 12 "Electrical
//      Characteristics and Recommended AC Operating Conditions" (-7E column), its
//      initialization, READ/PRECHARGE and AUTO REFRESH sections; JEDEC SDR SDRAM rules.
//
// Plain Verilog-2005 (plus $fatal under STRICT); runs on Icarus (-g2012) and Verilator.
// Written from the datasheet, not from hwsim's cycle model: it shares no code with it.
//
// Every timing parameter is in clocks.  Commands are sampled on the rising edge when
// cke = 1 and cs_n = 0, decoded by (ras_n, cas_n, we_n) as in sdram_pins.md.  Cycle n is
// the n-th rising edge (the first is 0).  Rules checked (one $display line per breach):
//   power-up   no command before T_POWERUP; before the first ACTIVATE: PRECHARGE all,
//              then >= 2 AUTO REFRESH, then LOAD MODE; only those commands until then
//   mode       LOAD MODE value must be burst BL, sequential, CAS latency CL, programmed-
//              length writes (all banks idle, tRP after the PRECHARGE)
//   tMRD       LOAD MODE -> any command
//   tRCD       ACTIVATE -> READ/WRITE, same bank
//   tRP        PRECHARGE (or auto precharge) -> ACTIVATE/REFRESH, same bank
//   tRAS       ACTIVATE -> PRECHARGE (min); open longer than T_RAS_MAX (max, 0: unchecked)
//   tRC        ACTIVATE -> ACTIVATE/REFRESH, same bank
//   tRRD       ACTIVATE -> ACTIVATE, another bank
//   tWR        last write beat -> PRECHARGE, same bank
//   tRFC       AUTO REFRESH -> any command
//   tREFI      refreshes owed: after power-up, k * T_REFI cycles owe k refreshes; owing
//              more than REFRESH_POSTPONE (8, JEDEC) is a breach (so no gap between two
//              refreshes may exceed 9 * tREFI, and the average rate is held)
//   closed     READ/WRITE to a bank with no open row
//   open       ACTIVATE to a bank whose row is open
//   burst      a READ burst cut short by PRECHARGE (earlier than READ + BL), READ or WRITE
//              (earlier than the previous READ + BL), or a WRITE while read data is on
//              the bus (earlier than READ + CL + BL)
// Counters (after power-up only): activates, reads (bursts), writes, precharges (commands;
// PRECHARGE all counts once), auto_precharges, refreshes.  STRICT=1 stops the run with
// $fatal at the first breach; otherwise `violations` counts them.
`timescale 1ns / 1ps

module sdram_checker #(
    parameter integer CL = 2,
    parameter integer BL = 8,
    parameter integer T_RCD = 2,
    parameter integer T_RP = 2,
    parameter integer T_RAS = 5,
    parameter integer T_RAS_MAX = 15000,
    parameter integer T_RC = 8,
    parameter integer T_RRD = 2,
    parameter integer T_WR = 2,
    parameter integer T_RFC = 9,
    parameter integer T_REFI = 976,
    parameter integer T_MRD = 2,
    parameter integer T_POWERUP = 0,
    parameter integer REFRESH_POSTPONE = 8,
    parameter integer BANKS = 4,
    parameter integer STRICT = 0
) (
    input wire clk,
    input wire cke,
    input wire cs_n,
    input wire ras_n,
    input wire cas_n,
    input wire we_n,
    input wire [1:0] ba,
    input wire [12:0] a,
    output reg [31:0] violations,
    output reg [31:0] activates,
    output reg [31:0] reads,
    output reg [31:0] writes,
    output reg [31:0] precharges,
    output reg [31:0] auto_precharges,
    output reg [31:0] refreshes,
    output reg [31:0] cycle,
    output reg ready
);
  localparam signed [39:0] NEVER = -40'sd1000000;
  localparam [3:0] C_LMR = 4'b0000, C_REF = 4'b0001, C_PRE = 4'b0010, C_ACT = 4'b0011;
  localparam [3:0] C_WR = 4'b0100, C_RD = 4'b0101;
  // Mode register: A2:0 burst length code, A3 sequential (0), A6:4 CAS latency, A9 = 0.
  localparam [12:0] MODE = (CL << 4) | (BL == 1 ? 0 : BL == 2 ? 1 : BL == 4 ? 2 : BL == 8 ? 3 : 7);

  reg open[0:BANKS-1];
  reg signed [39:0] t_act[0:BANKS-1];  // last ACTIVATE
  reg signed [39:0] t_pre[0:BANKS-1];  // last PRECHARGE (or auto-precharge start)
  reg signed [39:0] t_rd[0:BANKS-1];  // last READ
  reg signed [39:0] t_wend[0:BANKS-1];  // cycle after the last write beat
  reg ras_max_flagged[0:BANKS-1];
  reg signed [39:0] last_act, last_rd, last_wr, last_ref, last_mrs;
  reg [1:0] last_act_bank;
  reg [2:0] init_step;  // 0: need PRECHARGE all; 1: refreshes; 2: need LOAD MODE; 3: done
  reg [3:0] init_refs;
  reg signed [39:0] owed, refi_timer;
  reg [3:0] cmd;
  reg signed [39:0] now;
  integer b;

  initial begin
    violations = 0;
    activates = 0;
    reads = 0;
    writes = 0;
    precharges = 0;
    auto_precharges = 0;
    refreshes = 0;
    cycle = 0;
    ready = 0;
    for (b = 0; b < BANKS; b = b + 1) begin
      open[b] = 0;
      t_act[b] = NEVER;
      t_pre[b] = NEVER;
      t_rd[b] = NEVER;
      t_wend[b] = NEVER;
      ras_max_flagged[b] = 0;
    end
    last_act = NEVER;
    last_act_bank = 0;
    last_rd = NEVER;
    last_wr = NEVER;
    last_ref = NEVER;
    last_mrs = NEVER;
    init_step = 0;
    init_refs = 0;
    owed = 0;
    refi_timer = 0;
  end

  function [8*8:1] name;
    input [3:0] c;
    case (c)
      C_LMR: name = "LMR";
      C_REF: name = "REFRESH";
      C_PRE: name = "PRE";
      C_ACT: name = "ACT";
      C_WR: name = "WRITE";
      C_RD: name = "READ";
      default: name = "NOP";
    endcase
  endfunction

  // One breach: the rule, the bank, this cycle, and the earlier command it conflicts with.
  task breach;
    input [8*10:1] rule;
    input integer bank;
    input [8*8:1] first;
    input signed [39:0] t_first;
    begin
      violations = violations + 1;
      $display("SDRAM VIOLATION %0s bank %0d cycle %0d: %0s at %0d -> %0s at %0d", rule, bank,
               now, first, t_first, name(cmd), now);
      if (STRICT != 0) $fatal(1, "sdram_checker: %0s violated (STRICT)", rule);
    end
  endtask

  // Checks shared by ACTIVATE and REFRESH on bank bk: tRP after its precharge, tRC.
  task check_idle_bank;
    input integer bk;
    begin
      if (now < t_pre[bk] + T_RP) breach("tRP", bk, "PRE", t_pre[bk]);
      if (now < t_act[bk] + T_RC) breach("tRC", bk, "ACT", t_act[bk]);
    end
  endtask

  // A PRECHARGE of open bank bk now: tRAS, burst cut, tWR.
  task check_precharge;
    input integer bk;
    begin
      if (now < t_act[bk] + T_RAS) breach("tRAS", bk, "ACT", t_act[bk]);
      if (now < t_rd[bk] + BL) breach("burst", bk, "READ", t_rd[bk]);
      if (now < t_wend[bk] - 1 + T_WR) breach("tWR", bk, "WRITE", t_wend[bk] - BL);
      open[bk] = 0;
      t_pre[bk] = now;
    end
  endtask

  // READ or WRITE to bank bk now (is_read), column command rules and auto precharge.
  task column_command;
    input integer bk;
    input is_read;
    reg signed [39:0] ap;
    begin
      if (!open[bk]) breach("closed", bk, "PRE", t_pre[bk]);
      if (now < t_act[bk] + T_RCD) breach("tRCD", bk, "ACT", t_act[bk]);
      if (now < last_rd + BL) breach("burst", bk, "READ", last_rd);
      if (!is_read && now < last_rd + CL + BL) breach("bus", bk, "READ", last_rd);
      if (is_read && now < last_wr + BL) breach("burst", bk, "WRITE", last_wr);
      if (is_read) begin
        t_rd[bk] = now;
        last_rd = now;
      end else begin
        t_wend[bk] = now + BL;
        last_wr = now;
      end
      if (a[10]) begin  // auto precharge: starts when a manual PRECHARGE first could
        ap = is_read ? now + BL : now + BL - 1 + T_WR;
        if (ap < t_act[bk] + T_RAS) ap = t_act[bk] + T_RAS;
        open[bk] = 0;
        t_pre[bk] = ap;
        if (ready) auto_precharges = auto_precharges + 1;
      end
    end
  endtask

  always @(posedge clk) begin
    now = cycle;
    cmd = (!cke || cs_n) ? 4'b0111 : {1'b0, ras_n, cas_n, we_n};
    if (cmd != 4'b0111) begin
      if (now < T_POWERUP) breach("power-up", ba, "NOP", 0);
      if (now < last_ref + T_RFC) breach("tRFC", ba, "REFRESH", last_ref);
      if (now < last_mrs + T_MRD) breach("tMRD", ba, "LMR", last_mrs);
      if (!ready && (cmd == C_ACT || cmd == C_RD || cmd == C_WR))
        breach("power-up", ba, "NOP", 0);
    end
    case (cmd)
      C_ACT: begin
        if (open[ba]) breach("open", ba, "ACT", t_act[ba]);
        check_idle_bank(ba);
        if (last_act_bank != ba && now < last_act + T_RRD) breach("tRRD", ba, "ACT", last_act);
        open[ba] = 1;
        t_act[ba] = now;
        ras_max_flagged[ba] = 0;
        last_act = now;
        last_act_bank = ba;
        if (ready) activates = activates + 1;
      end
      C_RD, C_WR: begin
        column_command(ba, cmd == C_RD);
        if (ready && cmd == C_RD) reads = reads + 1;
        if (ready && cmd == C_WR) writes = writes + 1;
      end
      C_PRE: begin
        if (a[10]) begin
          for (b = 0; b < BANKS; b = b + 1) if (open[b]) check_precharge(b);
          if (init_step == 0) init_step = 1;
        end else if (open[ba]) check_precharge(ba);
        if (ready) precharges = precharges + 1;
      end
      C_REF: begin
        for (b = 0; b < BANKS; b = b + 1) begin
          if (open[b]) breach("refresh", b, "ACT", t_act[b]);
          check_idle_bank(b);
        end
        last_ref = now;
        if (init_step == 1 && init_refs < 15) init_refs = init_refs + 1;
        if (ready) begin
          refreshes = refreshes + 1;
          owed = owed - 1;
        end
      end
      C_LMR: begin
        for (b = 0; b < BANKS; b = b + 1) begin
          if (open[b]) breach("mode", b, "ACT", t_act[b]);
          if (now < t_pre[b] + T_RP) breach("tRP", b, "PRE", t_pre[b]);
        end
        if (a != MODE) breach("mode", 0, "LMR", now);
        if (init_step == 0 || (init_step == 1 && init_refs < 2)) breach("power-up", 0, "NOP", 0);
        else if (!ready) begin
          init_step = 3;
          ready = 1;
        end
        last_mrs = now;
      end
      default: ;
    endcase
    // Refresh debt and the maximum row-open time, once power-up is over.
    if (ready) begin
      refi_timer = refi_timer + 1;
      if (T_REFI > 0 && refi_timer >= T_REFI) begin
        refi_timer = 0;
        owed = owed + 1;
        if (owed > REFRESH_POSTPONE) begin
          cmd = 4'b0111;
          breach("tREFI", 0, "REFRESH", last_ref);
        end
      end
    end
    for (b = 0; b < BANKS; b = b + 1)
      if (T_RAS_MAX > 0 && open[b] && !ras_max_flagged[b] && now > t_act[b] + T_RAS_MAX) begin
        ras_max_flagged[b] = 1;
        breach("tRAS max", b, "ACT", t_act[b]);
      end
    cycle <= cycle + 1;
  end
endmodule
