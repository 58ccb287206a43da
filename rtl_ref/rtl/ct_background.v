// ct_background: dark / background frame subtraction, out = requant(frame - dark)
// (chiptwin.dsp.frame_ops.subtract_background_fixed, BackgroundConfig).
//
// Registers: input (IN_*) . dark (DK_*) . diff (full precision, signed, frac max(IN_F, DK_F),
// never overflows) . output (OUT_*, one rounding RMODE, then OMODE).
// Each beat carries one pixel of a frame and the dark reference word of the same pixel.
// Timing: output registered, latency 1 cycle, one beat per cycle; in_ready = !out_valid | out_ready.
// out_sat / out_wrap flag the beat on the output port; cnt_* count them at the output handshake.
`default_nettype none

module ct_background #(
    parameter integer IN_W = 13, parameter integer IN_F = 0, parameter integer IN_S = 0,
    parameter integer DK_W = 17, parameter integer DK_F = 4, parameter integer DK_S = 0,
    parameter integer OUT_W = 16, parameter integer OUT_F = 2, parameter integer OUT_S = 1,
    parameter integer RMODE = 5,
    parameter integer OMODE = 1,
    parameter integer CNT_W = 48
) (
    input  wire             clk,
    input  wire             rst,
    input  wire             in_valid,
    output wire             in_ready,
    input  wire [IN_W-1:0]  in_x,
    input  wire [DK_W-1:0]  in_dark,
    output reg              out_valid,
    input  wire             out_ready,
    output reg  [OUT_W-1:0] out_y,
    output reg              out_sat,
    output reg              out_wrap,
    output wire [CNT_W-1:0] cnt_out_sat,
    output wire [CNT_W-1:0] cnt_out_wrap
);
    localparam integer F = (IN_F > DK_F) ? IN_F : DK_F;
    localparam integer XW = IN_W + (IN_S != 0 ? 0 : 1);      // as signed
    localparam integer DW = DK_W + (DK_S != 0 ? 0 : 1);
    localparam integer XA = XW + F - IN_F;                   // aligned to F
    localparam integer DA = DW + F - DK_F;
    localparam integer SW = (XA > DA ? XA : DA) + 1;         // the diff register

    wire [XW-1:0] xs;
    wire [DW-1:0] ds;
    ct_ext #(.IW(IN_W), .OW(XW), .SIGNED(IN_S)) u_xs (.x(in_x), .y(xs));
    ct_ext #(.IW(DK_W), .OW(DW), .SIGNED(DK_S)) u_ds (.x(in_dark), .y(ds));
    wire [XA-1:0] xa;
    wire [DA-1:0] da;
    generate
        if (F > IN_F) begin : g_xsh
            assign xa = {xs, {(F - IN_F){1'b0}}};
        end else begin : g_x
            assign xa = xs;
        end
        if (F > DK_F) begin : g_dsh
            assign da = {ds, {(F - DK_F){1'b0}}};
        end else begin : g_d
            assign da = ds;
        end
    endgenerate
    wire [SW-1:0] xw, dw;
    ct_ext #(.IW(XA), .OW(SW), .SIGNED(1)) u_xw (.x(xa), .y(xw));
    ct_ext #(.IW(DA), .OW(SW), .SIGNED(1)) u_dw (.x(da), .y(dw));
    wire [SW-1:0] diff = xw - dw;

    wire [OUT_W-1:0] y;
    wire sat, wrap;
    ct_requant #(
        .IW(SW), .SH(F - OUT_F), .RMODE(RMODE), .OW(OUT_W), .OSIGNED(OUT_S), .OMODE(OMODE)
    ) u_out (.x(diff), .y(y), .sat(sat), .wrap(wrap));

    assign in_ready = ~out_valid | out_ready;
    wire in_fire = in_valid & in_ready;
    wire out_fire = out_valid & out_ready;

    ct_events #(.W(1), .CNT_W(CNT_W)) u_ev_out (
        .clk(clk), .rst(rst), .en(out_fire), .sat(out_sat), .wrap(out_wrap),
        .cnt_sat(cnt_out_sat), .cnt_wrap(cnt_out_wrap)
    );

    always @(posedge clk) begin
        if (rst) begin
            out_valid <= 1'b0;
        end else begin
            if (in_ready) out_valid <= in_valid;
        end
    end

    always @(posedge clk) begin
        if (in_fire) begin
            out_y <= y;
            out_sat <= sat;
            out_wrap <= wrap;
        end
    end
endmodule

`default_nettype wire
