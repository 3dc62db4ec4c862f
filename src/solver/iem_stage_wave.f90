!> Work space of RK4's stages taken as one wavefront over the bands of a rank's chunks
!> (model_t's rate_stages, docs/architecture.md "RK4's stages as one wavefront"): each
!> stage sweeps a band once the stage before it has passed every node the band's cells
!> reach, so that a band's state, forces and new state are read by every stage while they
!> are still in the processor's caches. Each stage keeps its own kernel rows and slots (its
!> sweep goes on from band to band as one sweep) and its own loads, load powers and reaction
!> powers until they are summed in stage order. On a rank with halo nodes each stage has its
!> strip (the cells near the halo, evaluated first, whose nodes include those the neighbours
!> receive) and its own bands of the other cells.
module iem_stage_wave
  use iem_kinds, only: wp, i8
  use iem_cell_table, only: cell_table_t, max_chunk
  use iem_cell_bands, only: cell_bands_t, band_nodes_default
  use iem_caches, only: l2_bytes
  use iem_cell_kernel, only: kernel_rows, kernel_slots_t
  use iem_cell_chunk, only: edge_row_t
  use iem_cell_split, only: cell_split_t
  implicit none
  private
  public :: stage_wave_t, wave_stages, wave_band_nodes

  !> The stages of a wavefront: RK4's (a wavefront takes 2-4, or 1-4).
  integer, parameter :: wave_stages = 4

  !> The kernel rows of one stage's sweep.
  type :: stage_rows_t
    type(edge_row_t), allocatable :: r(:)
  end type stage_rows_t

  !> One stage's cells on a rank with halo nodes: its strip (the cells within a few cells of
  !> the halo nodes, evaluated first), the bands of the other cells, and its schedule.
  type :: stage_strip_t
    !> The strip as the split's boundary chunks (on the kernel's plain path; the corners also
    !> reached by other chunks in side slots), the rest as its interior chunks.
    type(cell_split_t) :: split
    !> The bands of the interior chunks; their runs leave out the strip's early nodes (the
    !> split's early: complete after the strip), which are the runs after the last band's.
    type(cell_bands_t) :: bands
    !> need(b): the band of the stage before after which every corner of band b's chunks is
    !> done (0: the stage before's strip is enough).
    integer, allocatable :: need(:)
    !> The other nodes of D (positions in the split's d_node) that band b completes:
    !> edge(edge_first(b) : edge_first(b + 1) - 1).
    integer, allocatable :: edge(:), edge_first(:)
    !> The early nodes' mass damping powers, kept until the bands' sum reaches them.
    real(wp), allocatable :: pw(:)
  end type stage_strip_t

  !> The wavefront's schedule and each stage's work space (made for one lattice's bands).
  type :: stage_wave_t
    !> On a rank without halo nodes: the wavefront's bands, and need(b): the band after which
    !> every corner of band b's chunks is done, so that the next stage may sweep band b once
    !> the stage before has passed band need(b).
    type(cell_bands_t) :: bands
    integer, allocatable :: need(:)
    !> The same for the model's bands (velocity Verlet's step and the next step's cells,
    !> iem_model_pair).
    integer, allocatable :: pair_need(:)
    !> Each stage's kernel rows and slots (and those of the strips, each evaluated in one
    !> call).
    type(stage_rows_t) :: rows(wave_stages), strip_rows
    type(kernel_slots_t) :: slots(wave_stages), strip_slots
    !> Each stage's loads (2, slots), load powers (slots), reaction powers and whether they
    !> enter the external power (prescribed dofs), and load scales (loads).
    real(wp), allocatable :: fx(:, :, :), pe(:, :), pr(:, :), scale(:, :)
    logical, allocatable :: on(:, :)
    !> On a rank with halo nodes (init_strips): whether made, and each stage's strip and bands.
    logical :: strips = .false.
    type(stage_strip_t) :: strip(wave_stages)
  contains
    procedure :: init => wave_init
    procedure :: init_strips => wave_init_strips
    procedure :: ready => wave_ready
    procedure :: free => wave_free
  end type stage_wave_t

contains

  !> The nodes a band of the wavefront completes on this machine: 2048 where a core's
  !> second-level cache holds at least 2 MiB, so that the four stages' span (about four
  !> bands, 120 bytes a node: 1 MB) stays in it; else band_nodes_default, the span then in
  !> the third-level cache (docs/benchmarks.md, "Issue 12's figures (thirty-fifth session)").
  integer function wave_band_nodes()
    wave_band_nodes = band_nodes_default
    if (l2_bytes() >= 2_i8*1024_i8**2) wave_band_nodes = 2048
  end function wave_band_nodes

  !> The wavefront's bands of the chunks cells of a rank without halo nodes (n_owned nodes),
  !> each completing at least band_nodes nodes, their schedule, the schedule of the model's
  !> bands (model_bands, for velocity Verlet) and the work space of n_slots loaded nodes,
  !> n_bc prescribed dofs and n_loads loads (the kernel rows are made at first use; nothing
  !> is made without the model's bands or without two bands of the wavefront).
  subroutine wave_init(this, cells, model_bands, n_owned, band_nodes, n_slots, n_bc, n_loads)
    class(stage_wave_t), intent(inout) :: this
    type(cell_table_t), intent(in) :: cells
    type(cell_bands_t), intent(in) :: model_bands
    integer, intent(in) :: n_owned, band_nodes, n_slots, n_bc, n_loads
    call this%free()
    if (.not. model_bands%active) return
    call this%bands%init(cells, n_owned, band_nodes=band_nodes)
    if (.not. this%bands%active) return
    this%need = band_needs(cells, this%bands, this%bands, .true.)
    this%pair_need = band_needs(cells, model_bands, model_bands, .true.)
    allocate(this%fx(2, n_slots, wave_stages), this%pe(n_slots, wave_stages), &
             this%pr(n_bc, wave_stages), this%on(n_bc, wave_stages), &
             this%scale(n_loads, wave_stages))
  end subroutine wave_init

  !> The schedule and work space of a rank with halo nodes (n_owned owned nodes of n_local)
  !> for its chunks cells: stage i's strip is the cells with a corner at most 4 - i cells
  !> from a halo node (4 - i + 1 = the split's width: stage 4's, the cells with a halo
  !> corner), so that the nodes stage i + 1's strip reaches, and the nodes the neighbours
  !> receive (the owned corners of cells with a halo corner), are complete after stage i's
  !> strip; the bands of each stage's other cells complete at least band_nodes nodes. Not
  !> made (strips false) where some stage has fewer than two bands.
  subroutine wave_init_strips(this, cells, n_owned, n_local, band_nodes, n_slots, n_bc, &
                              n_loads)
    class(stage_wave_t), intent(inout) :: this
    type(cell_table_t), intent(in) :: cells
    integer, intent(in) :: n_owned, n_local, band_nodes, n_slots, n_bc, n_loads
    logical, allocatable :: early(:)
    integer, allocatable :: band_of(:)
    integer :: i, k, b, nb, d, n_e
    call this%free()
    allocate(early(n_local))
    do i = 1, wave_stages
      associate(st => this%strip(i))
        call st%split%init(cells, n_owned, n_local, wave_stages + 1 - i)
        call st%bands%init(st%split%cells_in, n_owned, st%split%d_node(st%split%early), &
                           band_nodes)
        if (.not. st%bands%active) then
          call this%free()
          return
        end if
        nb = st%bands%n_bands()
        ! need: against the stage before's bands, leaving out its early nodes
        if (i > 1) st%need = band_needs(st%split%cells_in, st%bands, this%strip(i - 1)%bands, &
                                        .false., early)
        early = .false.
        early(st%split%d_node(st%split%early)) = .true.
        ! the other nodes of D by the band that completes them
        allocate(band_of(size(st%split%d_node)))
        band_of = 0
        b = 1
        do d = 1, size(st%split%d_node)
          if (early(st%split%d_node(d))) cycle
          do while (st%bands%done(b) < st%split%d_node(d))
            b = b + 1
          end do
          band_of(d) = b
        end do
        allocate(st%edge_first(nb + 1))
        st%edge = pack([(d, d = 1, size(band_of))], band_of > 0)
        k = 1
        do b = 1, nb
          st%edge_first(b) = k
          do while (k <= size(st%edge))
            if (band_of(st%edge(k)) > b) exit
            k = k + 1
          end do
        end do
        st%edge_first(nb + 1) = k
        deallocate(band_of)
        n_e = size(st%split%early)
        allocate(st%pw(n_e))
      end associate
    end do
    this%strips = .true.
    allocate(this%fx(2, n_slots, wave_stages), this%pe(n_slots, wave_stages), &
             this%pr(n_bc, wave_stages), this%on(n_bc, wave_stages), &
             this%scale(n_loads, wave_stages))
  end subroutine wave_init_strips

  !> need(b) of the bands of cells (after whose band need(b) of before every corner of band b's
  !> chunks is done): with same, before is bands itself and need(b) >= b; with early, corners
  !> marked in it are done before any band (need 0 where all are).
  function band_needs(cells, bands, before, same, early) result(need)
    type(cell_table_t), intent(in) :: cells
    type(cell_bands_t), intent(in) :: bands, before
    logical, intent(in) :: same
    logical, intent(in), optional :: early(:)
    integer, allocatable :: need(:)
    integer :: b, j, k, m, i, top, nb, nb0, first, cq(4, max_chunk)
    nb = bands%n_bands()
    nb0 = before%n_bands()
    allocate(need(nb))
    k = 0
    if (same) k = 1
    do b = 1, nb
      ! the largest corner of the band's chunks (but early ones)
      top = 0
      first = 1
      if (b > 1) first = bands%last_chunk(b - 1) + 1
      do j = first, bands%last_chunk(b)
        if (cells%chunks(3, j) == 1 .and. .not. present(early)) then
          m = cells%chunks(2, j)
          top = max(top, cells%chunks(4, j) + m, cells%chunks(5, j) + m)
        else
          call cells%chunk_corners(j, cq, m)
          do i = 1, m
            if (present(early)) then
              top = max(top, maxval(cq(:, i), mask=.not. early(cq(:, i))))
            else
              top = max(top, maxval(cq(:, i)))
            end if
          end do
        end if
      end do
      if (same) k = max(k, b)
      if (top > 0) k = max(k, 1)
      do while (k > 0 .and. k < nb0)
        if (before%done(k) >= top) exit
        k = k + 1
      end do
      need(b) = k
    end do
  end function band_needs

  !> Whether the schedule is made (for bands), its kernel rows made here at first use.
  logical function wave_ready(this)
    class(stage_wave_t), intent(inout) :: this
    integer :: i
    wave_ready = allocated(this%need) .or. this%strips
    if (.not. wave_ready) return
    do i = 1, wave_stages
      if (.not. allocated(this%rows(i)%r)) this%rows(i)%r = kernel_rows()
    end do
    if (this%strips .and. .not. allocated(this%strip_rows%r)) this%strip_rows%r = kernel_rows()
  end function wave_ready

  !> Release everything (the wavefront is then not ready).
  subroutine wave_free(this)
    class(stage_wave_t), intent(inout) :: this
    integer :: i
    if (allocated(this%need)) deallocate(this%need)
    if (allocated(this%pair_need)) deallocate(this%pair_need)
    this%bands = cell_bands_t()
    if (allocated(this%fx)) deallocate(this%fx, this%pe, this%pr, this%on, this%scale)
    this%strips = .false.
    do i = 1, wave_stages
      this%strip(i) = stage_strip_t()
    end do
    if (allocated(this%strip_rows%r)) deallocate(this%strip_rows%r)
    if (allocated(this%strip_slots%at)) deallocate(this%strip_slots%at)
    do i = 1, wave_stages
      if (allocated(this%rows(i)%r)) deallocate(this%rows(i)%r)
      if (allocated(this%slots(i)%at)) deallocate(this%slots(i)%at)
    end do
  end subroutine wave_free
end module iem_stage_wave
