"""What the paper states (its captions' parameters and table 1 as printed) and the record of
one figure: :class:`PaperFigure`, its rows of the paper's numbers beside ours."""

from __future__ import annotations

from dataclasses import dataclass, field

# Figure 2's caption: A = 1/3, K = 0.5, W = 0.06 m, d_p = 2 mm (eps = 1/30), u(0) = 0.2,
# rho_p = 2940 kg/m^3, phi = 25 deg, fully rough wall (N = 1); L = 10 unless a figure varies it.
A = 1.0 / 3.0
K = 0.5
L = 10.0
N = 1.0
EPS2 = 1.0 / 30.0
EPS4 = 1.0 / 600.0
U0 = 0.2
FIG2_MATERIAL = {"d_p": 0.002, "rho_p": 2940.0, "phi": 25.0}
# Figure 3 (Natarajan et al.): W = 0.0255 m, d_p = 3 mm, phi = 28 deg.
FIG3_MATERIAL = {"d_p": 0.003, "rho_p": 2940.0, "phi": 28.0}
EPS3 = 0.003 / 0.0255
# Table 1 (Tuzun & Nedderman): W = 0.155 m, d_p = 2.29 mm, rho_p = 1180, phi = 30, delta = 8 deg.
TABLE1_MATERIAL = {"d_p": 0.00229, "rho_p": 1180.0, "phi": 30.0}
TABLE1_W = 0.155
TABLE1_DELTA_DEG = 8.0
# Figure 12: nu = 0.603 as its caption prints it.
FIG12_NU = 0.603
# Appendix A: the paper's series start for eq:a2.
PAPER_XI1 = 1e-5
APPENDIX_A_EPS = 0.33

# Table 1 as the paper prints it (kN/m^2; H in m): the experiments of Tuzun & Nedderman.
TABLE1_EXPERIMENTS = (
    ("0.91", "2.7\u20133.6", "4.0\u20135.1", "0.30\u20130.39", "0.29\u20130.35"),
    ("1.07", "2.7\u20132.9", "3.8\u20134.6", "0.30", "0.41\u20130.58"),
    ("1.22", "2.7\u20133.6", "4.6\u20135.7", "0.52\u20130.65", "0.58\u20130.76"),
)
NONE = "\u2014"  # the paper's empty cell
TABLE1_COSSERAT = ("7.97", "1.12")
TABLE1_KINETIC = ("2.51", "1.15")


@dataclass
class Row:
    """One stated value: what, the paper's words or number, ours, and why they differ."""

    what: str
    paper: str
    ours: str
    note: str = ""


@dataclass
class PaperFigure:
    """What one of the paper's figures (or table 1, or Appendix A) needs drawn and said.

    Attributes
    ----------
    key : str
        ``"figure2"`` ... ``"figure12"``, ``"table1"``, ``"appendix_a"``.
    title : str
        The paper's caption, shortened, with its parameters.
    data : dict
        Arrays and numbers the figure draws.
    rows : list of Row
        The paper's stated numbers beside ours.
    """

    key: str
    title: str
    data: dict = field(default_factory=dict)
    rows: list = field(default_factory=list)

    def rows_markdown(self) -> str:
        """The rows as a Markdown table (what, paper, ours, note)."""
        lines = ["| what | paper | ours | note |", "|---|---|---|---|"]
        cell = lambda text: str(text).replace("|", "\\|")  # noqa: E731
        lines += [f"| {cell(r.what)} | {cell(r.paper)} | {cell(r.ours)} | {cell(r.note)} |"
                  for r in self.rows]
        return "\n".join(lines)

    def __str__(self) -> str:
        import textwrap

        lines = textwrap.wrap(self.title, 88)
        for r in self.rows:
            lines.append(f"- {r.what}")
            lines += textwrap.wrap(f"paper: {r.paper}  |  ours: {r.ours}", 88,
                                   initial_indent="    ", subsequent_indent="    ")
            if r.note:
                lines += textwrap.wrap(r.note, 88, initial_indent="    ",
                                       subsequent_indent="    ")
        return "\n".join(lines)
