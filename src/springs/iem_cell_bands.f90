!> Bands of a rank's chunks of cells for an evaluation whose pass over the nodes follows the
!> cells band by band (docs/architecture.md, "The node pass band by band"): after the chunks of
!> a band, the nodes that no later chunk has as a corner have all their cells' forces, and the
!> pass can update them while their values and forces are still in the processor's caches,
!> instead of in a second sweep over the whole state.
module iem_cell_bands
  use iem_cell_table, only: cell_table_t
  implicit none
  private
  public :: cell_bands_t, band_nodes_default

  !> The fewest nodes a band completes (its nodes' state and forces, about 48 bytes a node,
  !> stay in the second-level cache); a rank with fewer than twice as many owned nodes is
  !> not banded.
  integer, parameter :: band_nodes_default = 16384

  !> The bands of one rank's chunks (made once for its lattice).
  type :: cell_bands_t
    !> Whether the evaluation goes band by band (a rank without halo nodes and with at least
    !> two bands; else nothing is allocated).
    logical :: active = .false.
    !> Band b is the chunks last_chunk(b - 1) + 1 .. last_chunk(b) (last_chunk(0) = 0); after
    !> it, the nodes 1 .. done(b) are corners of no later chunk (done(n_bands) = n_owned).
    integer, allocatable :: last_chunk(:), done(:)
  contains
    procedure :: init => bands_init
    procedure :: n_bands => bands_n_bands
  end type cell_bands_t

contains

  !> The bands of the chunks of cells of a rank whose nodes 1..n_owned are owned and
  !> n_owned+1..n_local halo nodes, each completing at least band_nodes nodes (default
  !> band_nodes_default); inactive with halo nodes or fewer than two bands.
  subroutine bands_init(this, cells, n_owned, n_local, band_nodes)
    class(cell_bands_t), intent(inout) :: this
    type(cell_table_t), intent(in) :: cells
    integer, intent(in) :: n_owned, n_local
    integer, intent(in), optional :: band_nodes
    integer, allocatable :: done(:), cq(:, :)
    integer :: nc, j, m, low, nb, last, least

    least = band_nodes_default
    if (present(band_nodes)) least = band_nodes
    if (allocated(this%last_chunk)) deallocate(this%last_chunk, this%done)
    this%active = .false.
    nc = cells%n_chunks()
    if (n_local > n_owned .or. n_owned < 2*least .or. nc < 2) return
    ! done(j): the nodes below the smallest corner of the chunks after j
    allocate(done(nc), cq(4, maxval(cells%chunks(2, :))))
    low = n_owned + 1
    do j = nc, 1, -1
      done(j) = min(n_owned, low - 1)
      if (cells%chunks(3, j) == 1) then
        ! consecutive rows: the first nodes of the two rows
        low = min(low, cells%chunks(4, j), cells%chunks(5, j))
      else
        call cells%chunk_corners(j, cq, m)
        low = min(low, minval(cq(:, 1:m)))
      end if
    end do
    ! cut a band where at least least more nodes are done, the last one at the end
    allocate(this%last_chunk(nc), this%done(nc))
    nb = 0
    last = 0
    do j = 1, nc
      if (j < nc .and. done(j) - last < least) cycle
      nb = nb + 1
      this%last_chunk(nb) = j
      this%done(nb) = done(j)
      last = done(j)
    end do
    ! a last band that completes few nodes joins the one before
    if (nb >= 2) then
      if (this%done(nb) - this%done(nb - 1) < least) then
        this%last_chunk(nb - 1) = this%last_chunk(nb)
        this%done(nb - 1) = this%done(nb)
        nb = nb - 1
      end if
    end if
    this%last_chunk = this%last_chunk(1:nb)
    this%done = this%done(1:nb)
    this%active = nb >= 2
    if (.not. this%active) deallocate(this%last_chunk, this%done)
  end subroutine bands_init

  !> The number of bands (0 when inactive).
  pure integer function bands_n_bands(this)
    class(cell_bands_t), intent(in) :: this
    bands_n_bands = 0
    if (this%active) bands_n_bands = size(this%last_chunk)
  end function bands_n_bands
end module iem_cell_bands
